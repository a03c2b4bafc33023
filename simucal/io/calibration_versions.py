"""The calibration file's earlier formats read as today's (io/calibration.py FORMAT): one step per version,
each taking a file's dict to the next version's, so that a file any earlier revision wrote loads
(tests/test_calibration_versions.py holds a file of each, as those revisions wrote them).

- `simucal.calibration/1` (the first revisions, to 2026-11-23): the sensor blocks as today's (M, bias,
  params, std, the model test), with no `layout`: the raw outputs' units and nominal scale factors, which
  `apply` divides by, stayed in the set's meta.json. Its layout is read from the set it names (`input`,
  beside the file or in the working folder), which must be the same bytes (`input_sha256`); the gyro's
  C_b_model is its `unification.C_b_d`, as format 2 writes it.
- `simucal.calibration/2`: today's. Keys it gained since (samples_sha256, the blocks' `test`, `verdict`,
  `thermal`, ...) are optional, so every file of it reads as written.
"""
from __future__ import annotations

from pathlib import Path

from simucal.io import records
from simucal.io.calibration_checks import CalibrationFileError, layout

FORMAT_1 = "simucal.calibration/1"


def _from_format_1(path: Path, d: dict) -> dict:
    """Format 1's dict as format 2's (module doc)."""
    from simucal.io import read_set  # the set's reader sits above this module in io/
    tried = [Path(d.get("input", "")), path.parent / d.get("input", "")]
    found = next((p for p in tried if d.get("input") and (p / "meta.json").is_file()), None)
    if found is None:
        raise CalibrationFileError(f"{path}: format {FORMAT_1!r} holds no layout (the raw outputs' units and "
                                   f"nominal scales were the set's meta.json), and its set {d.get('input')!r} is "
                                   "neither beside the file nor in the working folder: put it there, or "
                                   "calibrate again")
    ms = read_set(found)
    if d.get("input_sha256") not in (None, ms.sha256):
        raise CalibrationFileError(f"{path}: format {FORMAT_1!r} takes its layout from its set, but {found} is not "
                                   f"the set it was calibrated from (sha256 {str(ms.sha256)[:12]}..., the file "
                                   f"names {str(d['input_sha256'])[:12]}...): put that set there, or calibrate again")
    out = {k: v for k, v in d.items() if k != "model"}  # model: {sensor: name}, the blocks' own in format 2
    out.update(format="simucal.calibration/2", layout=layout(ms))
    for sensor in out["layout"]["sensors"]:
        out[sensor] = {**d[sensor], "effects": {}, "model_source": "built-in"}  # format 1 had no effects
    unification = d.get("unification") or {}
    if "gyro" in out and "C_b_d" in unification:
        out["gyro"]["C_b_model"] = unification["C_b_d"]
    return out


STEPS = {FORMAT_1: _from_format_1}  # each earlier format: the step to the next one


def upgraded(path: Path, d: dict, current: str) -> records.JSONObject:
    """The file's dict in format `current`, through the steps from its own; an unknown format refused."""
    while d.get("format") != current:
        fmt = d.get("format")
        if fmt not in STEPS:
            raise CalibrationFileError(f"{path}: format {fmt!r}, expected {current!r}"
                                       + (" or an earlier one (" + ", ".join(STEPS) + "); a newer simucal wrote it, "
                                          "or it is not a calibration file" if fmt else ""))
        d = STEPS[fmt](path, d)
    return d
