"""`simucal diagnose` on a stream (a hand-placed session), what differs from a turntable test (the
registry of kinds of data: methods.py): the accelerometers tested on the static poses the
hand-placed calibration finds, the gyro against its moves (diagnose_moves.py), and |f| over time."""
from __future__ import annotations

import numpy as np

from simucal import io
from simucal.errors import CalibrationError
from simucal.fit.apply import model_inputs
from simucal.fit.aux_inputs import AuxInputs, columns_at
from simucal.fit.results import SensorDiagnosis
from simucal.handheld.diagnose_moves import diagnose_moves
from simucal.handheld.poses import acc_from_poses, pose_observations
from simucal.io.records import JSONObject


def observations(ms):
    """(Observations, None, a segment per pose) of the stream's static poses, as the hand-placed
    calibration finds them (no plan and no table angles: None where a turntable test has segments)."""
    obs, _, poses = pose_observations(ms)
    return obs, None, [io.Segment(i, "static", None, None, None, 0.0) for i in range(len(poses))]


def diagnose_gyro(ms, gyro_model, add, truth, acc_model) -> SensorDiagnosis:
    """The gyro's block: a full T and a bias fit over the moves, judged against the poses' directions
    of the accelerometer model acc_model (its effects too)."""
    if gyro_model != "gyro_baseline":
        raise CalibrationError(f"{ms.path}: on a stream the gyro is fit as a full T and a bias over the moves, so "
                               f"the model {gyro_model} does not apply; add effects with --add gyro.<effect>.<axis>")
    obs, det, am, fa, _, _ = acc_from_poses(ms, acc_model)
    return diagnose_moves(ms, obs, det, am, fa, tuple(add), truth)


def stream_summary(ms, max_points=4000) -> JSONObject:
    """A continuous stream for the report: |f| over time (decimated), calibrated by the
    hand-placed accelerometer fit, and the static intervals found (the gyro's moves are in
    the gyro block, diagnose_moves)."""
    _, det, am, fa, _, _ = acc_from_poses(ms)
    t = ms.samples["t_s"]
    step = max(len(t) // max_points, 1)
    rows = np.arange(0, len(t), step)
    f = model_inputs(am, fa.vector(am.params), ms.acc_g()[rows],  # calibrated specific force, g
                     AuxInputs(columns_at(ms.samples, rows, t_ref_c=ms.t_ref_c)), ms.path / "samples.csv")
    return {"t_s": t[::step].tolist(), "acc_norm_g": np.linalg.norm(f, axis=1).tolist(),
            "static_detection": det.as_dict(t)}
