"""`simucal noise` (issue 26, item 3): the Allan deviation against allantools, the IEEE 952 terms
recovered from simulated noise of known size, Kalibr's imu.yaml in SI, and refusals."""
import json

import allantools
import numpy as np
import pytest
from click.testing import CliRunner

from simucal.allan import allan_variance, taus
from simucal.cli import main
from simucal.handheld.simulate import write_still
from simucal.turntable.simulate import Scenario, write

DT = 0.01
ARW_DEG_SQRT_H = 0.1     # gyro white noise N = 6 (deg/h) sqrt(s)
VRW_G_SQRT_S = 50e-6     # accelerometer white noise, 50 ug/sqrt(Hz)
RRW_DPH_SQRT_S = 5 / 60  # gyro rate random walk, 5 deg/h/sqrt(h)


def _run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def _still(folder, seconds=1800.0, rrw=RRW_DPH_SQRT_S, seed=0, move=False):
    return write_still(folder, seconds, DT, ARW_DEG_SQRT_H, rrw, VRW_G_SQRT_S, seed, move)


def _with_gap(folder):
    """Lose 100 samples mid-recording (a logger's dropout)."""
    lines = (folder / "samples.csv").read_text().splitlines(keepends=True)
    (folder / "samples.csv").write_text("".join(lines[:3000] + lines[3100:]))
    return folder


def test_the_allan_deviation_agrees_with_allantools():
    rng = np.random.default_rng(1)
    y = rng.standard_normal(20000) + 0.01 * np.cumsum(rng.standard_normal(20000))
    m = taus(len(y))
    avar, _ = allan_variance([y], DT, m)
    _, adev, _, _ = allantools.oadev(y, rate=1 / DT, data_type="freq", taus=m * DT)
    assert len(adev) == len(m)
    np.testing.assert_allclose(np.sqrt(avar), adev, rtol=1e-12)


def test_pooling_stretches_is_one_sum_over_them():
    """Two stretches pooled give the sums of squares of each, over the counts of both."""
    rng = np.random.default_rng(2)
    a, b = rng.standard_normal(3000), rng.standard_normal(5000)
    m = np.array([1, 4, 16])
    both, n = allan_variance([a, b], DT, m)
    va, na = allan_variance([a], DT, m)
    vb, nb = allan_variance([b], DT, m)
    np.testing.assert_allclose(both, (va * na + vb * nb) / (na + nb), rtol=1e-12)


def test_white_noise_is_recovered_and_kalibr_gets_it_in_si(tmp_path):
    d = _still(tmp_path / "still")
    r = _run("noise", d, "-o", tmp_path / "n.json", "--html", tmp_path / "n.html", "--kalibr", tmp_path / "imu.yaml")
    assert r.exit_code == 0, r.output
    rep = json.loads((tmp_path / "n.json").read_text())
    for a in "xyz":
        arw = rep["gyro"]["axes"][a]["sheet"]["N"]
        vrw = rep["acc"]["axes"][a]["sheet"]["N"]
        assert arw["unit"] == "deg/sqrt(h)" and abs(arw["value"] - ARW_DEG_SQRT_H) < 3 * arw["std"] + 0.01 * ARW_DEG_SQRT_H
        assert vrw["unit"] == "ug/sqrt(Hz)" and abs(vrw["value"] - 1e6 * VRW_G_SQRT_S) < 0.02 * 1e6 * VRW_G_SQRT_S
    yaml = dict(line.split(": ") for line in (tmp_path / "imu.yaml").read_text().splitlines() if not line[0] == "#")
    assert float(yaml["gyroscope_noise_density"]) == pytest.approx(ARW_DEG_SQRT_H / 60 * np.pi / 180, rel=0.02)
    assert float(yaml["accelerometer_noise_density"]) == pytest.approx(VRW_G_SQRT_S * 9.80665, rel=0.02)
    assert float(yaml["update_rate"]) == pytest.approx(1 / DT)
    assert float(yaml["gyroscope_random_walk"]) > 0 and float(yaml["accelerometer_random_walk"]) > 0
    assert "<img src=\"data:image/png;base64," in (tmp_path / "n.html").read_text()


def test_a_rate_random_walk_raises_the_long_taus(tmp_path):
    """With a rate random walk the fitted K (or the bound Kalibr gets) grows; without, it is small."""
    got = {}
    for name, rrw in (("walk", 10 * RRW_DPH_SQRT_S), ("white", 0.0)):
        d = _still(tmp_path / name, seconds=1200.0, rrw=rrw, seed=3)
        assert _run("noise", d, "-o", tmp_path / f"{name}.json", "--kalibr", tmp_path / f"{name}.yaml").exit_code == 0
        yaml = dict(x.split(": ") for x in (tmp_path / f"{name}.yaml").read_text().splitlines() if x[0] != "#")
        got[name] = float(yaml["gyroscope_random_walk"])
    assert got["walk"] > 5 * got["white"]


def test_the_static_segments_of_a_raw_turntable_set_are_pooled(tmp_path):
    write(tmp_path / "t", Scenario(rate_hz=20.0, static_s=20.0), 1)
    r = _run("noise", tmp_path / "t", "-o", tmp_path / "n.json")
    assert r.exit_code == 0, r.output
    assert "static segments, pooled" in r.output


@pytest.mark.parametrize("setup, named", [
    (lambda p: _still(p / "m", seconds=60.0, move=True), "moves during the recording"),
    (lambda p: (write(p / "m", Scenario(), 1), p / "m")[1], "not their averages"),
    (lambda p: _with_gap(_still(p / "m", seconds=60.0)), "has gaps"),
])
def test_what_has_no_allan_deviation_is_refused(tmp_path, setup, named):
    d = setup(tmp_path)
    r = _run("noise", d, "-o", tmp_path / "n.json")
    assert r.exit_code == 2 and named in r.output and not (tmp_path / "n.json").exists()


def test_calibrate_takes_each_segments_noise_from_the_allan_curve(tmp_path):
    """calibrate --noise: an averaged row's noise is the Allan curve at the seconds it averages (meta's
    average_s, a compatible extension of the spec), not white noise alone; refused without average_s."""
    from simucal.fit.noise import load_curves
    # white noise only, sized so that a 10 s mean has the simulator's per-row noise (1e-5 g, 0.01 deg/h)
    write_still(tmp_path / "still", 600.0, DT, 0.01 / 60 * np.sqrt(10), 0.0, 1e-5 * np.sqrt(10), seed=1)
    assert _run("noise", tmp_path / "still", "-o", tmp_path / "n.json").exit_code == 0
    write(tmp_path / "set", Scenario(plan="fibonacci48", state_noise=False), 3)
    r = _run("calibrate", tmp_path / "set", "--noise", tmp_path / "n.json", "-o", tmp_path / "c.json")
    assert r.exit_code == 2 and "average_s" in r.output and not (tmp_path / "c.json").exists()
    meta = json.loads((tmp_path / "set" / "meta.json").read_text())
    (tmp_path / "set" / "meta.json").write_text(json.dumps({**meta, "average_s": 10.0}))
    r = _run("calibrate", tmp_path / "set", "--noise", tmp_path / "n.json", "-o", tmp_path / "c.json")
    assert r.exit_code == 0, r.output
    cal = json.loads((tmp_path / "c.json").read_text())
    for s, per_row in (("acc", 1e-5), ("gyro", 0.01)):
        assert cal[s]["chi2"] is not None and cal[s]["p_value"] > 1e-3  # a chi-square test, not the F test
        assert "Allan curve" in cal[s]["noise"]["text"] and f"{per_row:.2g}" in cal[s]["noise"]["text"]
    # with a rate random walk a long mean is noisier than white noise over sqrt(n) says: at the longest tau
    # measured (200 s of a 30-minute record), and past it the curve keeps that excess (it goes on as white
    # noise from there: the walk is measured at only ~5 std, load_curves)
    write_still(tmp_path / "walk", 1800.0, DT, ARW_DEG_SQRT_H, RRW_DPH_SQRT_S, VRW_G_SQRT_S, seed=2)
    assert _run("noise", tmp_path / "walk", "-o", tmp_path / "w.json").exit_code == 0
    curve = load_curves(tmp_path / "w.json")["gyro"]
    assert curve.tau_max_s == pytest.approx(200.0, rel=1e-6)
    white = ARW_DEG_SQRT_H * 60 / np.sqrt(np.array([200.0, 600.0]))
    assert np.all(curve(200.0) > 1.5 * white[0]) and np.all(curve(600.0) > 1.5 * white[1])
    assert np.allclose(curve(0.1), ARW_DEG_SQRT_H * 60 / np.sqrt(0.1), rtol=0.1)


def test_a_recording_too_short_for_the_tau_asked_is_refused(tmp_path):
    d = _still(tmp_path / "still", seconds=60.0)
    r = _run("noise", d, "-o", tmp_path / "n.json", "--tau-max-s", 10)
    assert r.exit_code == 2 and "--tau-max-s 6.67 at most" in r.output and not (tmp_path / "n.json").exists()
    r = _run("noise", d, "-o", tmp_path / "n.json", "--tau-max-s", 2)
    assert r.exit_code == 0, r.output
    assert max(json.loads((tmp_path / "n.json").read_text())["gyro"]["tau_s"]) <= 2.0 + 1e-9


def test_noise_beyond_the_measured_taus_is_white_and_said(tmp_path):
    """A raw turntable set's own static segments give an Allan curve to a ninth of a segment; a short
    record fits long-tau terms by chance, so calibrate --noise carries the curve on as white noise
    past its last tau and says so: the chi-square then sits at its dof (the review found 0.42 times)."""
    from simucal.calibrate import calibrate
    from simucal.turntable.simulate import Scenario, write
    write(tmp_path / "raw", Scenario(rate_hz=100.0), 3)
    r = CliRunner().invoke(main, ["noise", str(tmp_path / "raw"), "-o", str(tmp_path / "n.json")])
    assert r.exit_code == 0, r.output
    cal = calibrate(tmp_path / "raw", noise=tmp_path / "n.json")
    assert 0.5 < cal.acc.chi2 / cal.acc.dof < 2.0, (cal.acc.chi2, cal.acc.dof)
    assert "beyond it their noise is its white part" in cal.acc.details["noise"]["source"]
