"""The lab's records on recordings other people made (../shared/data): imu_tk's Xsens hand session and imucal's
two Ferraris sessions, each calibrated, recorded in a store under a serial, certified from its record and the
unit's history read back. What each certificate says is what its file holds: the Xsens model fails its tests
(its u is mostly the misfit), a Ferraris accelerometer's six poses give no test (untested, not passed)."""
import re
from pathlib import Path

import numpy as np
import pytest

import simucal
from simucal.io.importers import import_ferraris_sections, import_imu_tk, import_imucal_annotated
from simucal.report.certificate import budget

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
NUMBERS = re.compile(r"<span class='n'>[^<]*</span>")


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    root = tmp_path_factory.mktemp("lab_real")
    import_imu_tk(DATA / "imu_tk-xsens" / "xsens_acc.mat", DATA / "imu_tk-xsens" / "xsens_gyro.mat", root / "xsens",
                  4096.0, 6258 * np.pi / 180, 45.4, 9.81744)
    fer = DATA / "imucal-ferraris"
    import_ferraris_sections(fer / "example_ferraris_session.csv", fer / "example_ferraris_session_list.json",
                             root / "example", 102.4, 49.6)
    import_imucal_annotated(fer / "annotated_session.csv", root / "annotated", 204.8, 2048.0, 16.4, 49.6,
                            turn_deg=360.0)
    store = simucal.Store(root / "lab.db")
    ids = {}
    for name, serial, when in (("xsens", "XSENS-1", "2026-01-01"), ("example", "IMUCAL-1", "2026-01-01"),
                               ("annotated", "IMUCAL-1", "2026-06-01")):
        simucal.save(root / f"{name}.json", simucal.calibrate(root / name))
        ids[name] = store.add(root / f"{name}.json", serial=serial, time=when)
    store.close()
    return root, ids


def test_each_real_sessions_certificate_from_its_record_is_its_files(lab):
    root, ids = lab
    for name, record in ids.items():
        page = simucal.certificate(store=root / "lab.db", record=record)
        own = simucal.certificate(root / f"{name}.json")
        assert NUMBERS.findall(page) == NUMBERS.findall(own) and len(NUMBERS.findall(page)) > 20, name
        cal = simucal.load(root / f"{name}.json")
        for sensor, block in cal.blocks():
            for r in budget(sensor, block):
                if r["noise"] is None:  # a share the file does not split: said on the page
                    assert r["misfit"] is None and block.verdict == "fails", (name, sensor, r)
                    continue
                parts = r["noise"] ** 2 + (r["table"] or 0.0) ** 2 + r["misfit"] ** 2
                assert np.isclose(parts, r["u"] ** 2, rtol=1e-9), (name, sensor, r)
        if name == "xsens":  # real poses and moves: more than noise, said so, and u carries the misfit
            assert cal.acc.verdict == cal.gyro.verdict == "fails"
            assert page.count("<p class='verdict bad'><b>") == 2 and "THE MODEL FAILS its test" in page
            # the poses' extra variance (model_error_std_g) is the misfit's share; the poses' noise alone the rest
            noise_only = cal.acc.details["std_noise"]
            for r in budget("acc", cal.acc):
                assert r["misfit"] > r["noise"] > 0
                if r["name"].startswith("bias_"):  # the parameter itself: its noise share is the file's
                    assert np.isclose(r["noise"], min(noise_only[r["own_name"]], r["u"]), rtol=1e-6), r
            # the moves' stds scale with their own scatter: the file cannot split them, and the page says so
            assert all(r["noise"] is None for r in budget("gyro", cal.gyro))
            assert "u includes the model's misfit, which the file does not split from the noise" in page
        else:  # six poses fit twelve parameters exactly: no test of the accelerometer's model
            assert cal.method == "ferraris" and cal.acc.verdict == "untested"
            assert "<p class='verdict unsure'><b>acc: the model is untested" in page


def test_a_real_units_history_gives_every_change_in_its_stds(lab):
    root, ids = lab
    history = simucal.Store(root / "lab.db").history("IMUCAL-1")
    assert [r["id"] for r in history["records"]] == [ids["example"], ids["annotated"]]
    changes = history["records"][1]["since_last"]["parameters"]
    assert len(changes) >= 12 and all(np.isfinite(p["z"]) for p in changes if p.get("z") is not None)
    assert history["verdict"].startswith("unit IMUCAL-1: 2 calibrations")
    assert history["trend"]["verdict"].startswith("unit IMUCAL-1: 2 calibrations by ferraris")
