"""Benchmark: simucal beside imucal on imucal's own Ferraris sessions.

simucal reads them through `simucal import` (poses at their nominal orientation, each 360 deg turn a
rate segment at the protocol's rate) and calibrates them with no --method: the Ferraris method, chosen
for six poses in opposite pairs. imucal (optional: pip install -e '.[bench]') runs on the same files as
its own docs show. imucal's model: raw = K R x + b (+ K_ga a for the gyro), so K R is compared with
simucal's M; biases in m/s^2 and deg/s. Real sessions have no truth, so the table gives what a
calibration should make true, for each tool: |f| - g at the six poses (simucal's fit makes it 0: no
test of simucal, a check of imucal), |mean f| - g over each turn (rows neither fit saw: the unit turns
about its vertical axis, so the mean specific force is g) and each turn's angle, the calibrated gyro
integrated over the turn (360 deg by the protocol; imucal fits its matrix to make it so, simucal fits
the turns' mean rates with the poses' bias).
Usage: python3 benchmarks/bench_imucal.py (two sessions of seconds: no size to choose)
"""
import tempfile
from pathlib import Path

import numpy as np

from simucal import io
from simucal.api.calibrating import calibrate
from simucal.errors import CalibrationError
from simucal.io.importers import import_ferraris_sections, import_imucal_annotated
from simucal.report.markdown import header

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "imucal-ferraris"
G = 9.81


def ours(folder, method=None):
    r = calibrate(folder, method=method)
    return r.acc.M, r.acc.bias * G, r.gyro.M, r.gyro.bias / 3600


def theirs(session):
    try:
        import pandas as pd
        from imucal import (
            FerrarisCalibration,
            ferraris_regions_from_df,
            ferraris_regions_from_section_list,
        )
    except ImportError:
        return None
    if session == "example":
        data = pd.read_csv(DATA / "example_ferraris_session.csv", header=0, index_col=0)
        sections = pd.read_json(DATA / "example_ferraris_session_list.json").T
        regions = ferraris_regions_from_section_list(data, sections)
        cal = FerrarisCalibration().compute(regions, 102.4, "m/s^2", "deg/s")
    else:
        data = pd.read_csv(DATA / "annotated_session.csv", header=0, index_col=[0, 1])
        regions = ferraris_regions_from_df(data)
        cal = FerrarisCalibration().compute(regions, 204.8, "a.u.", "a.u.")
    return cal.K_a @ cal.R_a, cal.b_a, cal.K_g @ cal.R_g, cal.b_g, cal.K_ga


def checks(folder, cal, to_si):
    """(|f| - g at the poses rms, |mean f| - g over the turns rms, each turn's angle) of a calibration
    (K R, b_a, K R_g, b_g[, K_ga]) in the set's own units scaled to m/s^2 and deg/s by to_si."""
    ms = io.read_set(folder)
    acc, gyro, t = ms.raw("acc") * to_si[0], ms.raw("gyro") * to_si[1], ms.samples["t_s"]
    Ka, ba, Kg, bg = (np.asarray(x, float) for x in cal[:4])
    K_ga = np.asarray(cal[4], float) if len(cal) > 4 else np.zeros((3, 3))
    f = (acc - ba) @ np.linalg.inv(Ka).T
    w = (gyro - bg - f @ K_ga.T) @ np.linalg.inv(Kg).T
    poses = [np.linalg.norm(f[ms.rows(s.segment)].mean(0)) - G for s in ms.segments if s.kind == "static"]
    turns = [s for s in ms.segments if s.kind == "rate"]
    held = [np.linalg.norm(f[ms.rows(s.segment)].mean(0)) - G for s in turns]
    angles = [np.linalg.norm(w[ms.rows(s.segment)].sum(0)) * float(np.median(np.diff(t))) for s in turns]
    return float(np.sqrt(np.mean(np.square(poses)))), float(np.sqrt(np.mean(np.square(held)))), angles


def show(name, cal):
    """One table row: acc M, acc bias, gyro M, gyro bias."""
    def fmt(m):
        return np.array2string(np.asarray(m), precision=4, suppress_small=True).replace("\n", "")
    print(f"| {name} | " + " | ".join(fmt(x) for x in cal) + " |")


def main():
    print(header(["session, tool", "acc M (K R)", "acc bias (m/s^2 or counts)", "gyro M (K R)",
                  "gyro bias (deg/s or counts)"]))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        ex, an = Path(tmp) / "ex", Path(tmp) / "an2"
        import_ferraris_sections(DATA / "example_ferraris_session.csv", DATA / "example_ferraris_session_list.json",
                                 ex, 102.4, 49.6)
        a = ours(ex)
        show("example, simucal", a)
        rows.append(("example", "simucal", checks(ex, a, (1.0, 1.0))))
        t = theirs("example")
        if t is None:
            print("| example, imucal | not installed (pip install -e '.[bench]') | | | |")
        else:
            show("example, imucal", t[:4])
            rows.append(("example", "imucal", checks(ex, t, (1.0, 1.0))))
        import_imucal_annotated(DATA / "annotated_session.csv", Path(tmp) / "an", 204.8, 2048.0, 16.4, 49.6)
        try:
            ours(Path(tmp) / "an")
            print("| annotated, simucal (-360 deg as imucal assumes) | calibrated: the sign check missed it | | | |")
        except CalibrationError as e:
            print(f"| annotated, simucal (-360 deg as imucal assumes) | refused: {str(e)[:160]}... | | | |")
        import_imucal_annotated(DATA / "annotated_session.csv", an, 204.8, 2048.0, 16.4, 49.6, turn_deg=360.0)
        a = ours(an)
        # simucal's outputs are counts / nominal: back to counts for imucal's a.u.
        a = (a[0], a[1] / G * 2048, a[2], a[3] * 16.4)
        show("annotated, simucal (+360 deg, as measured)", a)
        counts = (G / 2048, 1 / 16.4)  # the set's counts to m/s^2 and deg/s
        rows.append(("annotated", "simucal", checks(an, (a[0], a[1] * counts[0], a[2], a[3] * counts[1]), counts)))
        t = theirs("annotated")
        if t is not None:
            # imucal's a.u. matrices map g-units (m/s^2 at its g) and deg/s to counts: scale to simucal's nominal
            t = (t[0] * G / 2048, t[1], t[2] / 16.4, t[3], t[4])
            show("annotated, imucal (assumes -360 deg)", t[:4])
            rows.append(("annotated", "imucal", checks(an, (t[0], t[1] * counts[0], t[2], t[3] * counts[1],
                                                            t[4] / 16.4), counts)))  # K_ga: counts per m/s^2
    print("\nimucal assumes each turn is -360 deg; the annotated session's turns are +360 deg, "
          "so its gyro K R comes out")
    print("near -I. simucal checks the sense of every rate segment against the gyro and refuses; imported with")
    print("--turn-deg 360 it calibrates normally.\n")
    print(header(["session", "tool", "|f| - g at the poses, rms (m/s^2)", "|mean f| - g over each turn, rms (m/s^2)",
                  "each turn's angle (deg)"]))
    for session, tool, (poses, held, angles) in rows:
        print(f"| {session} | {tool} | {poses:.2e} | {held:.2e} | {', '.join(f'{x:.3f}' for x in angles)} |")
    for session in ("example", "annotated"):
        both = {tool: c for s, tool, c in rows if s == session}
        if len(both) == 2:
            near = {k: min(both, key=lambda tool: f(both[tool])) for k, f in (
                ("|mean f| - g over the turns", lambda c: c[1]),
                ("the turns' angles", lambda c: np.sqrt(np.mean(np.square(np.abs(c[2]) - 360)))))}
            print(f"\n{session}: nearer the truth on " + "; on ".join(f"{k}: {v}" for k, v in near.items()))


if __name__ == "__main__":
    main()
