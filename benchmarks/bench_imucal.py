"""Benchmark: simucal beside imucal on imucal's own Ferraris sessions.

simucal reads them through `simucal import` (poses at their nominal
orientation, each 360 deg turn a rate segment at the protocol's rate) and
calibrates them by the multi-position method, which for these poses is the
Ferraris method. imucal (optional: pip install -e '.[bench]') runs on the same
files as its own docs show. imucal's model: raw = K R x + b (+ K_ga a for the
gyro), so K R is compared with simucal's M; biases in m/s^2 and deg/s.
Usage: python3 benchmarks/bench_imucal.py (two sessions of seconds: no size to choose)
"""
import tempfile
from pathlib import Path

import numpy as np

from simucal.calibrate import calibrate
from simucal.errors import CalibrationError
from simucal.io.importers import import_ferraris_sections, import_imucal_annotated
from simucal.report.markdown import header

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "imucal-ferraris"
G = 9.81


def ours(folder):
    r = calibrate(folder, "multiposition")
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
    return cal.K_a @ cal.R_a, cal.b_a, cal.K_g @ cal.R_g, cal.b_g


def show(name, cal):
    """One table row: acc M, acc bias, gyro M, gyro bias."""
    def fmt(m):
        return np.array2string(np.asarray(m), precision=4, suppress_small=True).replace("\n", "")
    print(f"| {name} | " + " | ".join(fmt(x) for x in cal) + " |")


def main():
    print(header(["session, tool", "acc M (K R)", "acc bias (m/s^2 or counts)", "gyro M (K R)",
                  "gyro bias (deg/s or counts)"]))
    with tempfile.TemporaryDirectory() as tmp:
        import_ferraris_sections(DATA / "example_ferraris_session.csv", DATA / "example_ferraris_session_list.json",
                                 Path(tmp) / "ex", 102.4, 49.6)
        show("example, simucal", ours(Path(tmp) / "ex"))
        t = theirs("example")
        if t is None:
            print("| example, imucal | not installed (pip install -e '.[bench]') | | | |")
        else:
            show("example, imucal", t)
        import_imucal_annotated(DATA / "annotated_session.csv", Path(tmp) / "an", 204.8, 2048.0, 16.4, 49.6)
        try:
            ours(Path(tmp) / "an")
            print("| annotated, simucal (-360 deg as imucal assumes) | calibrated: the sign check missed it | | | |")
        except CalibrationError as e:
            print(f"| annotated, simucal (-360 deg as imucal assumes) | refused: {str(e)[:160]}... | | | |")
        import_imucal_annotated(DATA / "annotated_session.csv", Path(tmp) / "an2", 204.8, 2048.0, 16.4, 49.6,
                                turn_deg=360.0)
        a = ours(Path(tmp) / "an2")
        # simucal's outputs are counts / nominal: back to counts for imucal's a.u.
        show("annotated, simucal (+360 deg, as measured)", (a[0], a[1] / G * 2048, a[2], a[3] * 16.4))
        t = theirs("annotated")
        if t is not None:
            # imucal's a.u. matrices map g-units (m/s^2 at its g) and deg/s to counts: scale to simucal's nominal
            show("annotated, imucal (assumes -360 deg)", (t[0] * G / 2048, t[1], t[2] / 16.4, t[3]))
    print("\nimucal assumes each turn is -360 deg; the annotated session's turns are +360 deg, so its gyro K R comes out")
    print("near -I. simucal checks the sense of every rate segment against the gyro and refuses; imported with")
    print("--turn-deg 360 it calibrates normally.")


if __name__ == "__main__":
    main()
