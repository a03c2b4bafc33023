"""Designing a rotation sequence (`simucal plan --sequence REF --design`): the moves (table axis,
angle) of a sequence that fills a table time, turned at the table's rate, and the rests after them
(each a weight times a common length), chosen to minimise the worst parameter std relative to its
target, the std a reference sequence (REF) reaches in its own table time. The papers hand-pick their
positions (dong2018's Table 1; PSINS' and Ren et al.'s 19); this chooses them for a unit and a time.

Each candidate is scored by `stds_of`, a function of its steps given by the caller: one pass of the
linearised filter over it simulated on the unit (systematic/observability.py, which the API joins to
this method-free search): the filter's covariance depends on the attitudes, rates, step lengths, noise
and updates, not on the measured values. The criterion is a soft maximum over the parameters of
log(std / target), (1 / SOFTNESS) log sum exp(SOFTNESS log(std / target)): at most log(n) / SOFTNESS
above the worst log ratio (n parameters near it), and lowered too by a change that helps a parameter
just under the worst (the hard maximum is flat over most changes, and a search on it alone stalls).

The search is an exchange algorithm (in the manner of Fedorov's for exact designs): it starts from
the best of the built-in sequences' move lists turned at the table's rate; each round tries
ROUND_TRIES random changes (one move replaced by another axis or angle, one removed, one inserted,
two neighbours swapped, one rest's weight times one of REST_FACTORS) and keeps the one that lowers the
criterion most without raising the worst ratio, else the one that lowers the worst ratio most; it
ends when PATIENCE rounds in a row find none or the evaluations are spent. Its random changes are
seeded: the same call designs the same sequence. It finds a good sequence, not the best one: two
seeds differ by under 1 % in the worst ratio.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from simucal.errors import InputError
from simucal.turntable.sequence import AXES, MIN_REST_S, SEQUENCES, Step, in_minutes

ANGLES_DEG = (90.0, -90.0, 180.0, -180.0, 360.0, -360.0)
MOVES = tuple((a, x, 1.0) for a in AXES for x in ANGLES_DEG)  # what a change may put in: axis, angle, rest weight
REST_FACTORS = (0.5, 0.8, 1.25, 2.0)  # a rest's weight changed: coarse, and fine for the end of a search
SOFTNESS = 30.0
ROUND_TRIES = 16
PATIENCE = 12
MIN_MOVES = 6  # fewer cannot turn each axis of the unit both ways with each up and down


@dataclass(frozen=True)
class ScoredSequence:
    """A sequence scored: its steps, each parameter's std (the observability's order), the criterion
    (module doc) and the worst std / target with its index."""
    steps: tuple[Step, ...]
    std: np.ndarray
    criterion: float
    worst: float
    worst_at: int


def score(stds_of, moves, rate_dps: float, minutes: float, target: np.ndarray) -> ScoredSequence | None:
    """The candidate of these moves (axis, angle, rest weight) at rate_dps with rests filling `minutes`
    in proportion to their weights; None where the moves leave a rest under sequence.MIN_REST_S."""
    shortest = min(w for _, _, w in moves)  # every rest at MIN_REST_S or more before fitting: all scale alike
    try:
        steps = tuple(in_minutes([Step(a, x, rate_dps, MIN_REST_S * w / shortest) for a, x, w in moves], minutes))
    except InputError:
        return None
    std = stds_of(steps)
    log_ratio = np.log(std / target)
    worst = int(np.argmax(log_ratio))
    soft = float(np.log(np.exp(SOFTNESS * (log_ratio - log_ratio[worst])).sum()) / SOFTNESS + log_ratio[worst])
    return ScoredSequence(steps, std, soft, float(np.exp(log_ratio[worst])), worst)


def moves_of(steps) -> list[tuple[str, float, float]]:
    """(axis, angle, rest weight) of each step (the weight relative to the shortest rest, which holds 1)."""
    shortest = min(s.rest_s for s in steps)
    return [(s.axis, s.angle_deg, s.rest_s / shortest) for s in steps]


def changes(moves, rng) -> list[tuple]:
    """ROUND_TRIES random neighbours of a move list (module doc), each different from it."""
    out: list[tuple] = []
    while len(out) < ROUND_TRIES:
        m, i = list(moves), int(rng.integers(len(moves)))
        kind = rng.integers(5)
        if kind == 0:
            m[i] = MOVES[rng.integers(len(MOVES))]
        elif kind == 1 and len(m) > MIN_MOVES:
            del m[i]
        elif kind == 2:
            m.insert(i, MOVES[rng.integers(len(MOVES))])
        elif kind == 3 and i + 1 < len(m):
            m[i], m[i + 1] = m[i + 1], m[i]
        elif kind == 4:
            m[i] = m[i][:2] + (m[i][2] * float(rng.choice(REST_FACTORS)),)
        if tuple(m) != tuple(moves) and tuple(m) not in out:
            out.append(tuple(m))
    return out


@dataclass(frozen=True)
class Design:
    """The search's result: the designed candidate, each built-in's at the table's rate in the same time
    (None: its moves do not fit), the built-in it started from, the evaluations spent."""
    best: ScoredSequence
    built_in: dict[str, ScoredSequence | None]
    start: str
    evaluations: int


def design(stds_of, minutes: float, target: np.ndarray, rate_dps: float, evaluations: int, seed: int = 0,
           progress=None) -> Design:
    """The search of the module doc. stds_of: each parameter's std over a list of steps (the target's
    order); progress: a callable wrapping the rounds' iterable (simucal.progress.bar) or None."""
    rng = np.random.default_rng(seed)
    starts = {name: score(stds_of, [(s.axis, s.angle_deg, 1.0) for s in make()], rate_dps, minutes, target)
              for name, make in SEQUENCES.items()}
    fitted = {k: c for k, c in starts.items() if c is not None}
    if not fitted:
        raise InputError(f"--minutes {minutes:g}: no built-in sequence's moves fit with rests of 5 s or more at "
                         f"{rate_dps:g} deg/s: give more minutes or a faster table")
    start = min(fitted, key=lambda k: fitted[k].criterion)
    best, spent = fitted[start], len(starts)
    rounds, idle = range(max(0, (evaluations - spent) // ROUND_TRIES)), 0
    for _ in (progress(rounds) if progress else rounds):
        tried = [score(stds_of, m, rate_dps, minutes, target)
                 for m in changes(moves_of(best.steps), rng)]
        spent += len(tried)
        scored = [c for c in tried if c is not None]
        softer = min((c for c in scored if c.worst <= best.worst), key=lambda c: c.criterion, default=None)
        lower = min(scored, key=lambda c: c.worst, default=None)
        if softer is not None and softer.criterion < best.criterion:
            best, idle = softer, 0
        elif lower is not None and lower.worst < best.worst:
            best, idle = lower, 0
        else:
            idle += 1
            if idle == PATIENCE:
                break
    return Design(best, starts, start, spent)
