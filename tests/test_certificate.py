"""A calibration's certificate (simucal.certificate, `simucal certificate`): its numbers are the calibration
file's (u the file's std, U = 2 u, the budget's parts adding up to u), the validation shown is of this
calibration, and its PDF, printed by a headless Chromium, renders to an image that is not blank and reads
as the page."""
import json
import math

import numpy as np
import pypdfium2 as pdfium
import pytest

import simucal
from cli_helpers import run
from simucal.api.demo_run import HIDDEN
from simucal.errors import SimucalError
from simucal.report.certificate import K, budget, coefficients
from simucal.report.numbers import value_digits
from simucal.report.numbers import eng


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A calibration whose accelerometer model fails (a hidden effect: its stds inflated by the misfit) on a
    table with a stated tilt (in the gyro's stds), its set's files hashed, and its validation on another set."""
    tmp = tmp_path_factory.mktemp("certificate")
    simucal.simulate(seed=4, effects=HIDDEN).write(tmp / "set")
    simucal.simulate(seed=5, effects=HIDDEN).write(tmp / "other")
    cal = tmp / "cal.json"
    simucal.save(cal, simucal.calibrate(tmp / "set"))
    validation = tmp / "validation.json"
    assert run("validate", cal, tmp / "other", "-o", validation).exit_code == 0
    return tmp, cal, validation


def test_the_certificates_numbers_are_the_files(files):
    tmp, cal_path, validation = files
    cal = simucal.load(cal_path)
    page = simucal.certificate(cal_path, validation=validation)
    raw = json.loads(cal_path.read_text())
    assert raw["acc"]["verdict"] == "fails" and "std_raw" in raw["acc"] and "table_tilt" in raw["gyro"]
    common = simucal.parameters(cal)
    for sensor, block in cal.blocks():
        rows = budget(sensor, block)  # the one vocabulary, as simucal.parameters gives it
        entries = common[(common["sensor"] == sensor) & np.isfinite(common["std"]) & (common["std"] > 0)]
        assert [(r["name"], r["own_name"], r["u"]) for r in rows] == \
            [(n, own if isinstance(own, str) else None, u) for n, own, u in
             zip(entries["name"], entries["own_name"], entries["std"])]
        for r in rows:
            assert r["U"] == K * r["u"] == 2 * r["u"] and f">{r['name']}<" in page
            if r["name"].startswith("bias_"):  # the bias is the parameter itself: u is the file's std of it
                assert math.isclose(r["u"], raw[sensor]["std"][r["own_name"]], rel_tol=1e-6), r
            parts = r["noise"] ** 2 + (r["table"] or 0.0) ** 2 + r["misfit"] ** 2
            assert math.isclose(parts, r["u"] ** 2, rel_tol=1e-9), (sensor, r)
            assert f">{eng(r['U'])}<" in page and f">{eng(r['value'], value_digits(r['value'], r['u']))}<" in page
        if sensor == "acc":  # the failing model: the misfit is most of u
            assert all(r["misfit"] > r["noise"] for r in rows) and all(r["table"] is None for r in rows)
        else:
            assert all(r["misfit"] == 0 and r["table"] is not None for r in rows)
            dK = [r["table"] / r["u"] for r in rows if r["own_name"] in ("dK_x", "dK_y", "dK_z")]  # moved alike
            assert len(dK) == 3 and min(dK) > 0.01
    digest = __import__("hashlib").sha256(cal_path.read_bytes()).hexdigest()
    assert digest in page and all(h in page for h in raw["input_sha256"]) and f"simucal {simucal.__version__}" in page
    assert (f"gyro on independent data ({tmp / 'other'}): at the noise floor" in page
            and "acc: THE MODEL FAILS its test" in page)
    assert ("<p class='verdict bad'><b>acc: THE MODEL FAILS" in page
            and "<p class='verdict ok'><b>gyro: the model passes" in page)


def test_a_model_no_test_judged_is_said_untested_not_passed(files, tmp_path):
    """The multi-position method gives no model test: its certificate says so, in amber, not as a pass."""
    tmp, _, _ = files
    cal = tmp_path / "multiposition.json"
    simucal.save(cal, simucal.calibrate(tmp / "set", method="multiposition"))
    page = simucal.certificate(cal)
    for sensor in ("acc", "gyro"):
        assert f"<p class='verdict unsure'><b>{sensor}: the model is untested: the method gives no test" in page
    assert "class='verdict ok'" not in page and "passes its test" not in page and "untested its test" not in page


def test_the_pdf_renders_and_reads_as_the_page(files, tmp_path):
    _, cal, validation = files
    r = run("certificate", cal, "-o", tmp_path / "c.html", "--pdf", tmp_path / "c.pdf", "--validation", validation)
    assert r.exit_code == 0, r.output
    assert (tmp_path / "c.html").read_text() == simucal.certificate(cal, validation=validation)
    doc = pdfium.PdfDocument(str(tmp_path / "c.pdf"))
    image = doc[0].render(scale=1.0).to_numpy()
    ink = np.mean(image.min(axis=2) < 128)  # the share of dark pixels: text and table rules
    assert image.shape[0] > 500 and 0.01 < ink < 0.5, ink
    text = " ".join(doc[i].get_textpage().get_text_bounded() for i in range(len(doc)))
    assert "Calibration certificate" in text and "U (k = 2)" in text and "Validation on independent data" in text
    assert "file://" not in text and "page.html" not in text  # no browser header or footer (its URL, its title)


def test_an_older_chromium_is_told_to_leave_out_the_header_too(tmp_path, monkeypatch):
    """Chromium before 111 knows --print-to-pdf-no-header, not --no-pdf-header-footer: both are given (a browser
    ignores a flag it does not know). A stand-in browser records what it was given and prints a PDF."""
    from simucal.report.pdf import html_to_pdf
    args = tmp_path / "args"
    fake = tmp_path / "old-chromium"
    fake.write_text("#!/bin/sh\nprintf '%s\\n' \"$@\" > " + str(args) + "\nfor a in \"$@\"; do case $a in "
                    "--print-to-pdf=*) printf '%%PDF-1.4' > \"${a#--print-to-pdf=}\";; esac; done\n")
    fake.chmod(0o755)
    monkeypatch.setenv("SIMUCAL_CHROMIUM", str(fake))
    assert html_to_pdf("<p>x</p>").startswith(b"%PDF")
    given = args.read_text().split("\n")
    assert "--print-to-pdf-no-header" in given and "--no-pdf-header-footer" in given and "--headless" in given


def test_no_browser_a_foreign_validation_and_no_overwrite_are_refused_writing_nothing(files, tmp_path, monkeypatch):
    tmp, cal, validation = files
    monkeypatch.setenv("SIMUCAL_CHROMIUM", str(tmp_path / "no-such-browser"))
    with pytest.raises(SimucalError, match="SIMUCAL_CHROMIUM=.*no such program"):
        simucal.certificate(cal, html=tmp_path / "c.html", pdf=tmp_path / "c.pdf")
    assert not list(tmp_path.iterdir())  # nothing written
    monkeypatch.delenv("SIMUCAL_CHROMIUM")
    copy = tmp_path / "copy.json"  # the same bytes under another name: the same calibration
    copy.write_bytes(cal.read_bytes())
    assert "<h2>Validation on independent data</h2>" in simucal.certificate(copy, validation=validation)
    (tmp_path / "b").mkdir()  # another calibration under the same name: refused by its sha256
    namesake = tmp_path / "b" / cal.name
    namesake.write_text(cal.read_text() + " ")  # another byte
    with pytest.raises(SimucalError, match=f"validates .*{cal.name} \\(sha256 .*\\), not .*b/{cal.name}"):
        simucal.certificate(namesake, validation=validation)
    legacy = tmp_path / "legacy.json"  # a report written before validate recorded the sha256: matched by name
    legacy.write_text(json.dumps({**json.loads(validation.read_text()), "calibration_sha256": None}))
    assert "<h2>Validation on independent data</h2>" in simucal.certificate(cal, validation=legacy)
    with pytest.raises(SimucalError, match="validates .*cal.json, not .*copy.json"):
        simucal.certificate(copy, validation=legacy)
    same = tmp_path / "same.json"  # validated on the data it was made from: not independent
    assert run("validate", cal, tmp / "set", "-o", same).exit_code == 0
    with pytest.raises(SimucalError, match="same.json: a validation on the data the calibration was made from"):
        simucal.certificate(cal, validation=same)
    before = cal.read_bytes()
    for given in (("-o", validation, "--validation", validation), ("-o", cal)):  # an input is never written over
        r = run("certificate", cal, *given)
        assert r.exit_code != 0 and "input" in r.output, r.output
    assert cal.read_bytes() == before and json.loads(validation.read_text())["format"] == "simucal.validation/1"


def test_a_thermal_certificate_gives_its_coefficients_and_each_parameters_temperature_part(tmp_path):
    """Three plateaus with a planted quadratic bias in temperature: the certificate lists every coefficient the
    file holds (value, u, U = 2 u), and beside u each parameter's temperature part, sqrt(max_T u(T)^2 -
    u(T_ref)^2) over the calibrated range, here recomputed from the file's covariance term by term."""
    effects = {"acc.bias_temperature.x": 2e-6, "acc.bias_temperature2.x": 5e-8}
    sets = [simucal.simulate(plan="fibonacci48", rate_hz=20, seed=seed, temperature_c=T, t_ref_c=25.0,
                             temperature_wander_c=0.3, effects=effects) for T, seed in ((0, 1), (25, 2), (50, 3))]
    path = tmp_path / "thermal.json"
    simucal.save(path, simucal.calibrate(sets, thermal=True, t_ref_c=25.0))
    raw = json.loads(path.read_text())
    page = simucal.certificate(path)
    th = raw["acc"]["thermal"]
    assert th["parameters"]["b_x"]["degree"] == 2  # the planted polynomial, found
    terms = {n: (own, c, u) for n, own, c, _, u, _ in coefficients("acc", simucal.load(path).acc)}
    for n, (own, c, u) in terms.items():  # the one vocabulary's coefficients, the method's own name beside each
        assert f">{n}<" in page and f">{eng(c)}<" in page and f">{eng(2 * u)}<" in page and f">{own}<" in page
    for k in (1, 2):  # the bias is the parameter itself: its coefficients are the file's
        own, c, u = terms[f"bias_x.T{k}"]
        assert own == f"b_x.T{k}" and math.isclose(c, th["parameters"]["b_x"]["coefficients"][k], rel_tol=1e-6)
        assert math.isclose(u, th["parameters"]["b_x"]["std"][k], rel_tol=1e-3)
    cov = th["covariance"]
    lo, hi = th["temperature_range_c"]
    rows = budget("acc", simucal.load(path).acc)
    assert [r["name"] for r in rows if r["name"].startswith("bias_")] == ["bias_x", "bias_y", "bias_z"]
    for r in rows:  # an entry's temperature part through J; the bias, the parameter itself, recomputed here
        assert (r["temperature"] > 0.1 * r["u"]) == (r["name"] == "bias_x"), r  # only the term the data hold
        if not r["name"].startswith("bias_"):
            continue
        own = r["own_name"]
        names = [own] + [f"{own}.T{k}" for k in range(1, th["parameters"][own]["degree"] + 1)]
        idx = [cov["names"].index(n) for n in names]
        C = np.asarray(cov["matrix"])[np.ix_(idx, idx)]
        var = [sum(C[i, j] * dT ** (i + j) for i in range(len(idx)) for j in range(len(idx)))
               for dT in np.linspace(lo - 25.0, hi - 25.0, 1001)]
        part = math.sqrt(max(max(var) - C[0, 0], 0.0))
        assert math.isclose(r["temperature"], part, rel_tol=1e-3, abs_tol=1e-12 * r["u"]), r
    assert "temperature: over the range, beside u" in page and "temperature coefficients" in page


def test_a_certificate_of_a_store_record_is_the_files_and_its_validation_matches_by_sha256(files, tmp_path):
    """`simucal certificate --store URL --record N`: the record's file, byte for byte, so the same numbers and
    sha256 as the file's certificate, and validate's report of the file is this record's; the store is an
    input, never written over; a file and a record at once, or a record the store lacks, are refused."""
    _, cal, validation = files
    store = tmp_path / "lab.db"
    assert run("store", "add", cal, "--store", store, "--serial", "SN-1").exit_code == 0
    page = simucal.certificate(store=store, record=1, validation=validation)
    own = simucal.certificate(cal, validation=validation)
    digest = __import__("hashlib").sha256(cal.read_bytes()).hexdigest()
    assert f"record 1 of Store(&#x27;{store}&#x27;) (sha256 {digest})" in page
    assert "Calibration certificate: unit SN-1" in page and "(no unit_serial" in own  # the serial the lab recorded
    numbers = __import__("re").compile(r"<span class='n'>[^<]*</span>")
    assert numbers.findall(page) == numbers.findall(own) and len(numbers.findall(own)) > 50  # every number the same
    r = run("certificate", "--store", store, "--record", 1, "-o", tmp_path / "c.html", "--validation", validation)
    assert r.exit_code == 0, r.output
    assert (tmp_path / "c.html").read_text() == page
    before = store.read_bytes()
    r = run("certificate", "--store", store, "--record", 1, "-o", store)
    assert r.exit_code != 0 and "input" in r.output and store.read_bytes() == before
    with pytest.raises(SimucalError, match="lab.db.*: no record 7"):
        simucal.certificate(store=store, record=7)
    with pytest.raises(SimucalError, match="a calibration file or a store's record"):
        simucal.certificate(cal, store=store, record=1)
    with pytest.raises(SimucalError, match="a calibration file or a store's record"):
        simucal.certificate()
