"""The static detector's gyro limit from the data and the intervals its rules drop."""
import json
from pathlib import Path

import numpy as np
import pytest

from simucal.api.calibrating import calibrate
from simucal.errors import CalibrationError
from simucal.handheld.static_detect import DetectSettings, detect_static
from simucal.io.importers import import_imu_tk

MPU = Path(__file__).resolve().parents[2] / "shared" / "data" / "mpu6050-hand" / "example_data_calibration.csv"


@pytest.fixture(scope="module")
def mpu6050(tmp_path_factory):
    """The real MPU-6050 hand session (README beside it: 100 Hz, raw counts, the 16-bit rails), as imu_tk's two
    files (time and three counts per row), with meta.json's full_scale at the rails."""
    tmp = tmp_path_factory.mktemp("mpu6050")
    d = np.loadtxt(MPU, delimiter=",", skiprows=5)  # Fs, Logging Type, Initialization time, Waiting time, names
    t = np.arange(len(d)) / 100.0
    np.savetxt(tmp / "acc.txt", np.c_[t, d[:, :3]], fmt="%.2f %d %d %d")
    np.savetxt(tmp / "gyro.txt", np.c_[t, d[:, 3:]], fmt="%.2f %d %d %d")
    import_imu_tk(tmp / "acc.txt", tmp / "gyro.txt", tmp / "set", 16384.0, 131.0, -32.9)
    meta = json.loads((tmp / "set" / "meta.json").read_text())
    meta["full_scale"] = {"gyro": [-32768, 32767]}
    (tmp / "set" / "meta.json").write_text(json.dumps(meta))
    return tmp / "set"


@pytest.mark.slow
def test_a_real_hand_session_keeps_its_poses(mpu6050):
    """A fixed floor tuned on simulated sessions (0.3 deg/s) dropped three of this session's nine poses and split a
    fourth (8 positions for 9 parameters: refused); the limit from the poses' own sway keeps all nine, each trimmed
    of its settling, and the 18 clipped gyro samples are named with the three moves they leave out."""
    cal = calibrate(mpu6050).to_json()
    det = cal["static_detection"]
    assert det["count"] - 1 >= 9, det["intervals_s"]  # the initial rest and the nine poses
    assert det["dropped"] == [] and det["trimmed"], det["trimmed"]
    limit = det["gyro_limit"]
    assert limit["set_by"].startswith("the poses' sway") and limit["limit_dps"] > limit["noise_dps"]
    assert 0.4 < limit["limit_dps"] < 1.0, limit
    assert sum(s["count"] for s in cal["gyro"]["saturation"]) == 18
    assert [m["reason"] for m in cal["gyro"]["moves_skipped"]] == ["saturated samples in the move"] * 3


@pytest.mark.slow
def test_too_few_poses_are_refused_naming_what_dropped_them(mpu6050):
    """At the old 0.3 deg/s the refusal names each interval the gyro dropped, its numbers, and the option that
    keeps it."""
    with pytest.raises(CalibrationError) as e:
        calibrate(mpu6050, detect=DetectSettings(gyro_limit_dps=0.3))
    text = str(e.value)
    assert "8 acc positions for 9 parameters" in text and "3 still intervals dropped" in text, text
    assert "interval 47.85-50.50 s dropped by the gyro limit" in text and "above the limit 0.3" in text, text
    assert "To relax: --gyro-limit-dps 0.33 keeps 1 more" in text, text
    from simucal import io
    from simucal.handheld.poses import pose_observations
    _, det, _ = pose_observations(io.read_set(mpu6050), DetectSettings(gyro_limit_dps=0.33))
    assert len(det.starts) == 9 and len(det.dropped) == 2  # which it does


def _stream(pieces, fs=100.0, seed=0):
    """acc (g) and gyro (deg/s) rows of still pieces joined by 1 s tilts of 30 deg about x; a still piece is
    (seconds, yaw rate (deg/s) as a function of its time)."""
    rng, g, acc, gyro = np.random.default_rng(seed), np.array([0, 0, 1.0]), [], []
    for k, (secs, rate) in enumerate(pieces):
        if k:
            n = int(fs)
            a = np.linspace(0, 1, n)[:, None] * (np.array([0, np.sin(0.5), np.cos(0.5)]) * (-1) ** k - g) + g
            acc.append(a + 0.05 * np.sin(np.linspace(0, np.pi, n))[:, None])
            gyro.append(np.tile([30.0, 0, 0], (n, 1)))
            g = a[-1] / np.linalg.norm(a[-1])
        n = int(secs * fs)
        acc.append(np.tile(g, (n, 1)))
        gyro.append(np.c_[np.zeros((n, 2)), rate(np.arange(n) / fs)])
    acc = np.vstack(acc) + rng.normal(0, 1e-3, (sum(map(len, acc)), 3))
    return acc, np.vstack(gyro) + rng.normal(0, 0.05, acc.shape), np.arange(len(acc)) / fs


def test_every_dropped_interval_is_named_with_its_rule():
    """A pose that wobbles about the vertical (2 deg/s, the accelerometers still), one too short and one turning
    throughout: each is listed with its rule and numbers; the still poses are kept, and the limit is the noise's
    (these poses are still: their sway is the noise's)."""
    still = lambda s: 0.0 * s  # noqa: E731
    acc, gyro, t = _stream([(8, still), (4, still), (4, lambda s: 2.0 * np.sin(2 * np.pi * s / 1.5)),
                            (1.5, still), (4, lambda s: 20.0 + 0 * s), (4, still)])
    d = detect_static(acc, t, gyro_dps=gyro)
    assert len(d.starts) == 3 and d.gyro_limit["set_by"].startswith("the rest's gyro noise"), d
    rules = {x["rule"]: x for x in d.dropped}
    assert set(rules) == {"gyro", "min_static_s", "gyro_drift"}, d.dropped
    wobble = rules["gyro"]
    assert wobble["max_dps"] > wobble["kept_from_limit_dps"] > 2 * d.gyro_threshold_dps, wobble
    assert wobble["text"].startswith(f"interval {wobble['t_s'][0]:.2f}-{wobble['t_s'][1]:.2f} s dropped by the gyro "
                                     "limit: its gyro windowed rate") and "--gyro-limit-dps" in wobble["text"]
    assert "dropped by --min-static-s: 0." in rules["min_static_s"]["text"]
    assert "from the rest's bias throughout" in rules["gyro_drift"]["text"]
    kept = detect_static(acc, t, DetectSettings(gyro_limit_dps=wobble["kept_from_limit_dps"] * 1.05), gyro_dps=gyro)
    assert len(kept.starts) == 4 and "gyro" not in {x["rule"] for x in kept.dropped}


@pytest.mark.slow
def test_a_calibration_prints_the_intervals_it_dropped(mpu6050):
    """The console (the calibration's warnings) lists each interval dropped, with its rule and numbers, and the
    gyro limit in force; the file's static_detection holds them."""
    cal = calibrate(mpu6050, detect=DetectSettings(gyro_limit_dps=0.5))
    det = cal.details["static_detection"]
    assert det["count"] == 9 and [x["rule"] for x in det["dropped"]] == ["gyro"], det["dropped"]
    line, = [w for w in cal.warnings if w.startswith("static detection:")]
    assert "interval 69.18-71.44 s dropped by the gyro limit" in line and "above the limit 0.5" in line, line
    assert "(kept from --gyro-limit-dps 0.63)" in line and "gyro limit 0.5 deg/s" in line, line
