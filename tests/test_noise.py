"""`simucal noise`: the Allan deviation against allantools, its
covariance against a brute-force sum, the IEEE 952 terms recovered from simulated noise of known
size with stds right over seeds and absent terms not reported, Kalibr's imu.yaml in SI (only when
complete), a stuck channel named, and refusals."""
import json

import allantools
import numpy as np
import pytest
from click.testing import CliRunner

from simucal import io
from simucal.fit.allan_terms import allan_variance, axis_report, taus
from simucal.cli import main
from simucal.fit import allan_cov
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


@pytest.mark.slow
def test_white_noise_is_recovered_and_kalibr_gets_it_in_si(tmp_path):
    d = _still(tmp_path / "still")
    r = _run("noise", d, "-o", tmp_path / "n.json", "--html", tmp_path / "n.html", "--kalibr", tmp_path / "imu.yaml")
    assert r.exit_code == 0, r.output
    rep = json.loads((tmp_path / "n.json").read_text())
    for a in "xyz":
        arw = rep["gyro"]["axes"][a]["sheet"]["N"]
        vrw = rep["acc"]["axes"][a]["sheet"]["N"]
        assert (arw["unit"] == "deg/sqrt(h)"
                and abs(arw["value"] - ARW_DEG_SQRT_H) < 3 * arw["std"] + 0.01 * ARW_DEG_SQRT_H)
        assert vrw["unit"] == "ug/sqrt(Hz)" and abs(vrw["value"] - 1e6 * VRW_G_SQRT_S) < 0.02 * 1e6 * VRW_G_SQRT_S
    yaml = dict(line.split(": ") for line in (tmp_path / "imu.yaml").read_text().splitlines() if not line[0] == "#")
    assert float(yaml["gyroscope_noise_density"]) == pytest.approx(ARW_DEG_SQRT_H / 60 * np.pi / 180, rel=0.02)
    assert float(yaml["accelerometer_noise_density"]) == pytest.approx(VRW_G_SQRT_S * 9.80665, rel=0.02)
    assert float(yaml["update_rate"]) == pytest.approx(1 / DT)
    assert float(yaml["gyroscope_random_walk"]) > 0 and float(yaml["accelerometer_random_walk"]) > 0
    assert "<img src=\"data:image/png;base64," in (tmp_path / "n.html").read_text()
    nxt = next(x for x in r.output.splitlines() if x.startswith("next: "))  # not the --kalibr command just run
    assert "--kalibr" not in nxt and f"--noise {tmp_path / 'n.json'}" in nxt, nxt
    import html
    page = html.unescape((tmp_path / "n.html").read_text())
    assert f"Next: <code>{nxt[len('next: '):]}</code>" in page  # the page's next step is the console's


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


@pytest.mark.slow
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
    # noise from there unless the walk is measured at 10 std, load_curves); 4x the walk of the other tests,
    # which 30 minutes do not show beyond 3 std
    write_still(tmp_path / "walk", 1800.0, DT, ARW_DEG_SQRT_H, 4 * RRW_DPH_SQRT_S, VRW_G_SQRT_S, seed=2)
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
    from simucal.api.calibrating import calibrate
    from simucal.turntable.simulate import Scenario, write
    write(tmp_path / "raw", Scenario(rate_hz=100.0), 3)
    r = CliRunner().invoke(main, ["noise", str(tmp_path / "raw"), "-o", str(tmp_path / "n.json")])
    assert r.exit_code == 0, r.output
    cal = calibrate(tmp_path / "raw", noise=tmp_path / "n.json")
    assert 0.5 < cal.acc.chi2 / cal.acc.dof < 2.0, (cal.acc.chi2, cal.acc.dof)
    assert "beyond it their noise is its white part" in cal.acc.details["noise"]["source"]


# the taus (in samples), the sample interval (s) and two stretches' lengths of the brute-force check
BRUTE_M, BRUTE_DT, BRUTE_LENGTHS = np.array([1, 2, 3, 5, 8, 13, 40]), 0.1, [400, 250]


@pytest.fixture(scope="module")
def brute_products():
    """For every pair of taus (a <= b) summed over the stretches, the sums sum(P_i * P_j) of the
    products P = map1 @ map2.T of each pair of components (white, walk, quantisation) of the noise's
    explicit linear maps onto every second difference (allan_cov's module doc): the brute force's
    matrix products once for every x (they do not depend on the noise's sizes)."""
    m, dt, lengths = BRUTE_M, BRUTE_DT, BRUTE_LENGTHS
    sums = np.zeros((len(m), len(m), 3, 3))
    for n in lengths:
        maps = []
        for mm in m:
            k = np.arange(n - 2 * mm)[:, None]
            j = np.arange(n)[None, :]
            white = dt * (((j >= k + mm) & (j < k + 2 * mm)).astype(float) - ((j >= k) & (j < k + mm)))
            walk = np.cumsum(white[:, ::-1], axis=1)[:, ::-1]  # e_l reaches every y_i with i >= l
            q = np.zeros((len(k), n + 1))
            for off, w in ((0, 1.0), (mm, -2.0), (2 * mm, 1.0)):
                q[np.arange(len(k)), np.arange(len(k)) + off] = w
            maps.append((white, walk, q))
        for a, m1 in enumerate(maps):
            for b, m2 in enumerate(maps[a:], start=a):  # cov[b, a] = cov[a, b]
                P = [u @ v.T for u, v in zip(m1, m2)]
                sums[a, b] += [[np.sum(Pi * Pj) for Pj in P] for Pi in P]
    return sums


def _brute_covariance(products, x):
    """cov of the Allan variance estimates from the explicit linear maps of each component's noise
    onto every second difference, summed over stretches: 2 sum(c ** 2) with c = N/dt P_white +
    K dt P_walk + Q P_q, expanded over the products' sums (brute_products)."""
    m, dt, lengths = BRUTE_M, BRUTE_DT, BRUTE_LENGTHS
    w = np.array([x["N"] / dt, x["K"] * dt, x["Q"]])
    upper = 2 * np.einsum("i,abij,j->ab", w, products, w)
    out = np.triu(upper) + np.triu(upper, 1).T
    total = np.array([sum(max(n - 2 * mm, 0) for n in lengths) for mm in m]) * (np.asarray(m) * dt) ** 2
    return out / (4 * np.outer(total, total))


@pytest.mark.parametrize("x", [{"Q": 0.3, "N": 2.0, "K": 0.7}, {"Q": 0.0, "N": 1.0, "K": 0.0},
                               {"Q": 0.0, "N": 0.0, "K": 1.0}, {"Q": 1.0, "N": 0.0, "K": 0.0}])
def test_the_covariance_of_the_allan_variance_is_the_brute_force_sum(brute_products, x):
    """Closed form (pieces summed directly or by Euler-Maclaurin) against the explicit sum, two
    stretches pooled: exact, to rounding."""
    got = allan_cov.covariance(allan_cov.basis(BRUTE_M, BRUTE_DT, BRUTE_LENGTHS), x)
    np.testing.assert_allclose(got, _brute_covariance(brute_products, x), rtol=1e-9)


def test_a_day_at_200_hz_with_a_strong_walk_has_a_positive_definite_covariance():
    """24 h at 200 Hz, a random walk of 10 deg/h/sqrt(h) over a white noise of 0.1
    deg/sqrt(h). The walk's filter correlation is exact at lags of the record's length (it was the
    difference of cubics of 1e21 there: minus 5.9 as the smallest eigenvalue of the correlation),
    and the covariance at the record's 60 taus is positive definite."""
    m1, m2 = 3, 1_000_000
    tri1 = np.minimum(np.arange(2 * m1 + 1), 2 * m1 - np.arange(2 * m1 + 1))
    tri2 = np.minimum(np.arange(2 * m2 + 1), 2 * m2 - np.arange(2 * m2 + 1))
    lags = np.array([-2 * m1 - 1, 0, 7, m2, 2 * m2 - 3, 2 * m2, 10 ** 7])
    brute = [int(tri1[max(0, -h):][:len(tri2) - h] @ tri2[max(0, h):][:len(tri1) - max(0, -h)]) if h < len(tri2) else 0
             for h in lags]
    np.testing.assert_allclose(allan_cov._walk(lags.astype(float), float(m1), float(m2)), brute, rtol=1e-12, atol=1e-3)
    dt, n = 1 / 200, 24 * 3600 * 200
    mats = allan_cov.basis(taus(n), dt, [n])
    cov = allan_cov.covariance(mats, {"N": (0.1 * 60) ** 2, "K": (10.0 / 60) ** 2})
    d = np.sqrt(np.diag(cov))
    assert np.linalg.eigvalsh(cov / np.outer(d, d))[0] > 0
    np.linalg.cholesky(cov / np.outer(d, d))


def test_a_covariance_not_positive_definite_is_refused_in_one_line():
    """What rounding might still leave is a one-line refusal naming the cause, not exit 3."""
    from simucal.errors import CalibrationError
    from simucal.fit.allan_fit import gls
    with pytest.raises(CalibrationError, match="not positive definite.*--tau-max-s"):
        gls(np.ones(3), np.ones((3, 1)), np.array([[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 1.0]]))


def test_absent_terms_are_not_reported_and_the_stds_are_right_over_seeds():
    """White noise + random walk only, 8 seeds x 6 channels of 2 h at 5 Hz: no quantisation,
    bias instability or ramp beyond 3 std on more than 5 % of (axis, term) pairs, and the white
    noise and random walk within their stds (rms z 0.75-1.33 on 24 draws each; the full 20-seed
    figure of 2 h is benchmarks/bench_allan.py's). Fitted as independent points the same data
    reported absent terms at 3-18 std."""
    dt, n = 0.2, 36000  # the walk's std is set by the record's length (30 min: 30 % of K^2, 3 std)
    m = taus(n)
    mats = allan_cov.basis(m, dt, [n])
    sizes = {"gyro": ("deg/h", 6.0, 20.0 / 60), "acc": ("g", 50e-6, 2e-6)}
    false, pairs, z = 0, 0, {"N": [], "K": []}
    for seed in range(8):
        rng = np.random.default_rng(100 + seed)
        for sensor, (unit, white, walk) in sizes.items():
            for _ in range(3):
                y = (white / np.sqrt(dt) * rng.standard_normal(n)
                     + np.cumsum(walk * np.sqrt(dt) * rng.standard_normal(n)))
                ax = axis_report(sensor, [y], dt, m, mats, unit)
                false += sum(ax["sheet"][t]["status"] == "seen" for t in ("Q", "B", "R"))
                pairs += 3
                for t, truth in (("N", white), ("K", walk)):
                    assert ax["sheet"][t]["status"] == "seen", (seed, sensor, t, ax["sheet"][t])
                    std = ax["sheet"][t]["std"] / ax["sheet"][t]["value"] * ax["terms"][t]
                    z[t].append((ax["terms"][t] - truth) / std)
    assert false <= 0.05 * pairs, (false, pairs)
    for t in z:
        assert 0.75 < np.sqrt(np.mean(np.square(z[t]))) < 1.33, (t, z[t])


@pytest.mark.slow
def test_a_term_not_seen_has_its_bound_everywhere(tmp_path):
    """White noise only: the random walk, quantisation, instability and ramp are "not seen" with a
    95 % bound in the JSON, the console and the page; the bound of the walk is what Kalibr gets."""
    d = _still(tmp_path / "still", seconds=600.0, rrw=0.0)
    r = _run("noise", d, "-o", tmp_path / "n.json", "--html", tmp_path / "n.html", "--kalibr", tmp_path / "k.yaml")
    assert r.exit_code == 0, r.output
    ax = json.loads((tmp_path / "n.json").read_text())["gyro"]["axes"]["x"]
    assert ax["sheet"]["N"]["status"] == "seen"
    for t in ("Q", "B", "K", "R"):
        assert ax["sheet"][t]["status"] == "not seen" and ax["sheet"][t]["bound_95"] > 0 and ax["terms"][t] == 0
    x_k, std_k = ax["fit"]["squares"]["K"]  # the walk stays in the model: its bound is its fit's
    assert ax["bounds"]["K"] == pytest.approx(np.sqrt(max(x_k, 0.0) + 1.645 * std_k), rel=1e-12)
    assert f"rate random walk not seen (< {ax['sheet']['K']['bound_95']:.2g} deg/h/sqrt(h), 95 %)" in r.output
    assert "not seen (&lt;" in (tmp_path / "n.html").read_text()
    yaml = dict(x.split(": ") for x in (tmp_path / "k.yaml").read_text().splitlines() if x[0] != "#")
    rep = json.loads((tmp_path / "n.json").read_text())
    bound = max(rep["gyro"]["axes"][a]["bounds"]["K"] for a in "xyz") * np.pi / 180 / 3600
    assert float(yaml["gyroscope_random_walk"]) == pytest.approx(bound, rel=1e-5)


def test_a_stuck_channel_is_named_and_kalibr_refused(tmp_path):
    d = _still(tmp_path / "still", seconds=120.0)
    lines = (d / "samples.csv").read_text().splitlines()
    col = lines[0].split(",").index("gz")
    rows = [line.split(",") for line in lines[1:]]
    for row in rows:
        row[col] = "3.0"
    (d / "samples.csv").write_text("\n".join([lines[0]] + [",".join(r) for r in rows]) + "\n")
    r = _run("noise", d, "-o", tmp_path / "n.json", "--html", tmp_path / "n.html")
    assert r.exit_code == 0, r.output
    assert ("z: stuck or dead: constant at 3 deg/h" in r.output
            and "quantisation" not in r.output.split("z: stuck")[1].splitlines()[0])
    assert "; STUCK: z stuck or dead" in r.output  # and the gyro's verdict says so
    gz = json.loads((tmp_path / "n.json").read_text())["gyro"]["axes"]["z"]
    assert "stuck" in gz and "terms" not in gz
    r = _run("noise", d, "-o", tmp_path / "m.json", "--kalibr", tmp_path / "k.yaml")
    assert r.exit_code == 2 and "gyro z is stuck or dead" in r.output
    assert not (tmp_path / "k.yaml").exists() and not (tmp_path / "m.json").exists()


def test_kalibr_is_refused_without_the_gyroscope(tmp_path):
    """Kalibr requires both sensors' densities and walks: an accelerometer-only recording writes none."""
    n = 6000
    rng = np.random.default_rng(4)
    io.write_set(tmp_path / "acc", {"acc_unit": "g", "gyro_unit": "deg/h"},
                 {"t_s": np.arange(n) * DT, "ax": rng.standard_normal(n) * 1e-4,
                                                        "ay": rng.standard_normal(n) * 1e-4,
                                                        "az": 1 + rng.standard_normal(n) * 1e-4})
    r = _run("noise", tmp_path / "acc", "-o", tmp_path / "n.json", "--kalibr", tmp_path / "k.yaml")
    assert r.exit_code == 2 and "gyroscope_noise_density and gyroscope_random_walk" in r.output
    assert not (tmp_path / "k.yaml").exists() and not (tmp_path / "n.json").exists()
    assert _run("noise", tmp_path / "acc", "-o", tmp_path / "n.json").exit_code == 0


def test_a_record_too_short_for_a_term_says_the_length_it_needs(tmp_path):
    """0.3 s at 100 Hz holds 3 taus: the white noise only; every other term is "too short" with the
    length that gives the taus it needs; 0.2 s is refused whole, and so is a --tau-max-s below 3 steps."""
    r = _run("noise", _still(tmp_path / "s3", seconds=0.3), "-o", tmp_path / "n.json")
    assert r.exit_code == 0, r.output
    sheet = json.loads((tmp_path / "n.json").read_text())["gyro"]["axes"]["x"]["sheet"]
    assert sheet["N"]["status"] == "seen"
    for t in ("Q", "B", "K", "R"):
        assert sheet[t]["status"] == "too short" and sheet[t]["needs_s"] == pytest.approx(0.36)
    assert "rate ramp record too short (needs 0.36 s)" in r.output
    r = _run("noise", _still(tmp_path / "s2", seconds=0.2), "-o", tmp_path / "m.json")
    assert r.exit_code == 2 and "its 3 taus need 0.27 s" in r.output and not (tmp_path / "m.json").exists()
    r = _run("noise", _still(tmp_path / "s60", seconds=60.0), "-o", tmp_path / "m.json", "--tau-max-s", 0.001)
    assert r.exit_code == 2 and "--tau-max-s 0.03 at least" in r.output and not (tmp_path / "m.json").exists()


def test_noise_of_a_warming_board_warns_that_its_drift_may_be_thermal(tmp_path):
    """A still record whose temperature rises 30 degC: the console, the page's verdicts and Kalibr's imu.yaml say
    the long-tau terms may be thermal, and how to take the thermal model out; at a steady temperature, nothing."""
    import simucal
    rng = np.random.default_rng(5)
    t = np.arange(0, 600.0, 0.02)
    for name, T in (("warm", 15 + 30 * (1 - np.exp(-t / 200))), ("steady", 25 + rng.normal(0, 0.1, len(t)))):
        acc = np.array([0.0, 0.0, 1.0]) + 1e-4 * (T - 25)[:, None] + rng.normal(0, 1e-3, (len(t), 3))
        gyro = 10.0 * (T - 25)[:, None] + rng.normal(0, 50.0, (len(t), 3))
        simucal.MeasurementSet.from_arrays(acc, gyro, acc_unit="g", gyro_unit="deg/h", t_s=t, temp_c=T,
                                           meta={"latitude_deg": 47.0}).write(tmp_path / name)
        r = CliRunner().invoke(main, ["noise", str(tmp_path / name), "-o", str(tmp_path / f"{name}.json"),
                                      "--kalibr", str(tmp_path / f"{name}.yaml")])
        assert r.exit_code == 0, r.output
        warned = "WARNING: the temperature changes by" in r.output
        assert warned == (name == "warm"), r.output
        assert ("# WARNING" in (tmp_path / f"{name}.yaml").read_text()) == warned
    report = json.loads((tmp_path / "warm.json").read_text())
    assert report["temperature"]["range_c"][1] - report["temperature"]["range_c"][0] > 25
    assert "simucal apply warm.json" in report["temperature"]["warning"]
