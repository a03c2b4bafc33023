"""The overlapping Allan variance of a long still recording, read a chunk at a time
(`simucal noise`: simucal.fit.allan_noise.characterise_folder).

The overlapping Allan variance (simucal.fit.allan_terms, IEEE 952-1997 Annex C eq. C.2) needs, per channel,
only the integrated output theta_k = sum_{i<k} y_i: sigma^2(m dt) = sum_k (theta_{k+2m} -
2 theta_{k+m} + theta_k)^2 / (2 m^2 (N - 2m)) in the units of y, exactly, for every m. So the
samples are read a chunk at a time (simucal.io.columnar: samples.csv or samples.parquet), each
chunk converted to g and deg/h and its cumulative sum appended to theta (float64, 8 bytes per
row and channel); the table of the file is never held. theta is taken of y less the first
chunk's mean (the Allan variance does not see a constant, and theta then keeps the digits of the
noise, not of a bias times the row count). Besides theta one pass keeps each channel's least,
greatest and first value (a stuck channel), and the steps of t_s (the sample clock and its gaps,
as simucal.fit.stillness.sample_step); the 1-s means of check_still are differences of the accelerometer's theta.

The sums over k run in blocks of BLOCK rows (the second differences stay in the processor's
cache), and the rows in ranges of CHUNK, one task each (simucal.sweeps.map_tasks): here, or on
Dask with --scheduler processes or a scheduler's address. On Dask theta is written to a temporary
folder (TMPDIR; the workers read it, so a remote cluster needs it on a shared file system) a part
at a time, and each task memory-maps the parts it reads: a recording larger than memory runs.
The terms are then fitted exactly as for a set read whole (simucal.fit.allan_fit).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from simucal.io import SAMPLE_COLS, columnar, units
from simucal.sweeps import map_tasks

CHUNK = 1 << 20  # theta's parts (values; 8 MiB) and the rows of one task
BLOCK = 1 << 15  # rows of one step of the sums: the windows and the difference stay in cache


class Theta:
    """One channel's theta, appended to a chunk at a time, held in parts of `size` values: arrays, or
    .npy files in `spill` (read by memory map: what a Dask worker is sent is the file names)."""

    def __init__(self, spill: Path | None = None, name="theta", size=CHUNK):
        self.n, self.spill, self.name, self.size = 0, spill, name, size
        self.parts: list[np.ndarray | Path] = []  # arrays, or with spill their .npy files
        self._buf: np.ndarray | None = np.zeros(self.size)  # None once closed
        self._fill = 1  # theta_0 = 0
        self._maps: dict[int, np.ndarray] = {}

    def extend(self, y: np.ndarray) -> None:
        """Append the cumulative sum of y, continuing from the last value (exactly as one cumsum)."""
        assert self._buf is not None  # not closed
        last = self._buf[self._fill - 1] if self._fill else self._last_part()[-1]
        theta = np.cumsum(np.r_[last, y])[1:]
        while len(theta):
            take = min(self.size - self._fill, len(theta))
            self._buf[self._fill:self._fill + take] = theta[:take]
            self._fill += take
            theta = theta[take:]
            if self._fill == self.size:
                self._flush()

    def _last_part(self) -> np.ndarray:
        return self._part(len(self.parts) - 1)

    def _flush(self) -> None:
        assert self._buf is not None  # called before close() lets go of it
        if self.spill is None:
            self.parts.append(self._buf[:self._fill].copy() if self._fill < self.size else self._buf)
        else:
            path = self.spill / f"{self.name}.{len(self.parts)}.npy"
            np.save(path, self._buf[:self._fill])
            self.parts.append(path)
        self.n += self._fill
        if self.spill is None:  # the full buffer is now a part
            self._buf = np.empty(self.size)
        self._fill = 0

    def close(self) -> Theta:
        if self._fill:
            self._flush()
        self._buf = None
        return self

    def __getstate__(self):  # sent to a worker: the parts (arrays or file names), no open maps
        return {**self.__dict__, "_maps": {}}

    def _part(self, i) -> np.ndarray:
        part = self.parts[i]
        if isinstance(part, np.ndarray):
            return part
        if i not in self._maps:
            self._maps[i] = np.load(part, mmap_mode="r")
        return self._maps[i]

    def window(self, lo: int, hi: int) -> np.ndarray:
        """theta[lo:hi] (hi - lo <= self.size): a view within one part, else the two parts' pieces joined."""
        i, j = lo // self.size, (hi - 1) // self.size
        if i == j:
            return self._part(i)[lo - i * self.size:hi - i * self.size]
        return np.concatenate([self._part(i)[lo - i * self.size:], self._part(j)[:hi - j * self.size]])

    def at(self, index: np.ndarray) -> np.ndarray:
        """theta at these indices."""
        part = index // self.size
        out = np.empty(len(index))
        for i in np.unique(part):
            out[part == i] = self._part(int(i))[index[part == i] - i * self.size]
        return out


def range_sums(theta: Theta, lo: int, hi: int, m_values) -> np.ndarray:
    """sum over k in [lo, hi) of (theta_{k+2m} - 2 theta_{k+m} + theta_k)^2 for each m (the k
    where all three exist); one task."""
    from threadpoolctl import threadpool_limits
    # BLAS's dot on one thread: with OpenBLAS's threads the sums of 1.44 M rows took 4.0 s of CPU, not 0.09 s
    # (blocks of 32,768; measured on the loaded 2-core machine)
    with threadpool_limits(1, "blas"):
        return _range_sums(theta, lo, hi, m_values)


def _range_sums(theta, lo, hi, m_values) -> np.ndarray:
    out, block = np.zeros(len(m_values)), min(BLOCK, theta.size)
    buf = np.empty(block)  # one buffer: a fresh array per block would be mapped and faulted in each time
    for i, m in enumerate(m_values):
        top = min(hi, theta.n - 2 * m)
        for a in range(lo, top, block):
            d = buf[:min(block, top - a)]
            np.multiply(theta.window(a + m, a + m + len(d)), 2.0, out=d)
            np.subtract(theta.window(a + 2 * m, a + 2 * m + len(d)), d, out=d)
            d += theta.window(a, a + len(d))
            out[i] += d @ d
    return out


def allan_variances(thetas: list[Theta], m_values, scheduler=None) -> list[np.ndarray]:
    """The overlapping Allan variance of each channel (module doc) at the cluster sizes m_values."""
    m_values = np.asarray(m_values, int)
    tasks = [(th, lo, min(lo + th.size, th.n), m_values) for th in thetas for lo in range(0, th.n, th.size)]
    sums = map_tasks(range_sums, tasks, scheduler)
    counts = np.maximum(thetas[0].n - 2 * m_values, 0)
    out, k = [], 0
    for th in thetas:
        parts = sum(1 for t in tasks if t[0] is th)
        with np.errstate(invalid="ignore", divide="ignore"):
            out.append(np.sum(sums[k:k + parts], axis=0) / (2.0 * m_values ** 2 * counts))
        k += parts
    return out


class Pass:
    """What one pass over the chunks keeps (module doc): theta, least, greatest and first value per
    channel (in g and deg/h), the steps of t_s."""

    def __init__(self, channels, spill, size=CHUNK):
        self.theta = {c: Theta(spill, c, size) for c in channels}
        self.lo = {c: np.inf for c in channels}
        self.hi = {c: -np.inf for c in channels}
        self.first, self.center, self.steps, self.last_t = {}, {}, [], None
        self.temp_c = [np.inf, -np.inf]  # the least and greatest temp_c, where the set has one

    def add(self, t: np.ndarray, y: dict, temp_c: np.ndarray | None = None) -> None:
        if temp_c is not None and len(temp_c):
            self.temp_c = [min(self.temp_c[0], float(temp_c.min())), max(self.temp_c[1], float(temp_c.max()))]
        self.steps.append(np.diff(t if self.last_t is None else np.r_[self.last_t, t]))
        self.last_t = t[-1]
        for c, v in y.items():
            if c not in self.first:
                self.first[c], self.center[c] = float(v[0]), float(np.mean(v))
            self.lo[c], self.hi[c] = min(self.lo[c], float(v.min())), max(self.hi[c], float(v.max()))
            self.theta[c].extend(v - self.center[c])

    def close(self):
        for th in self.theta.values():
            th.close()
        steps, self.steps = np.concatenate(self.steps), []  # the parts let go
        return steps


def read_pass(folder, meta, sensors, spill, size=CHUNK, temperature=False) -> tuple[Pass, np.ndarray]:
    """One pass over the set's samples, a chunk at a time: (what it keeps, the steps of t_s); theta
    held in parts of `size` values; temperature: temp_c's range too."""
    channels = [c for s in sensors for c in (SAMPLE_COLS[:3] if s == "acc" else SAMPLE_COLS[3:])]
    kept = Pass(channels, spill, size)
    for chunk in columnar.chunks(folder, ["t_s"] + channels + (["temp_c"] if temperature else [])):
        y = {}
        for s in sensors:
            cols = SAMPLE_COLS[:3] if s == "acc" else SAMPLE_COLS[3:]
            raw = np.column_stack([chunk[c] for c in cols])
            conv = units.acc_to_g(raw, meta) if s == "acc" else units.gyro_to_dph(raw, meta)
            y.update({c: np.ascontiguousarray(conv[:, j]) for j, c in enumerate(cols)})
        kept.add(chunk["t_s"], y, chunk["temp_c"] if temperature else None)
    return kept, kept.close()
