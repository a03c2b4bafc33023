"""For the store's tests: a real PostgreSQL server of the tests' own (initdb and pg_ctl in a temporary folder on
a free port, as the postgres user where the tests run as root, stopped at the end), and calibration files of
simulated units written through simucal's own writer: one calibration of a simulated set, each unit and visit
its parameters drawn anew from the file's own covariance (so that a change between two of them is chi^2 where
nothing was planted), a planted drift added on some."""
from __future__ import annotations

import glob
import os
import shutil
import socket
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from simucal.io import calibration

DRIFT_PARAM = "gyro.b_z"    # the planted drift, in the exact method's own parameter
DRIFT_ENTRY = "gyro.bias_z"  # it in the one vocabulary: the store's rows, a history's changes, a trend


def _pg_bin() -> Path:
    found = sorted(glob.glob("/usr/lib/postgresql/*/bin/initdb"), key=lambda p: int(Path(p).parts[-3]))
    assert found or shutil.which("initdb"), "PostgreSQL is not installed: apt-get install -y postgresql (.ci/run)"
    return Path(found[-1] if found else shutil.which("initdb")).parent  # type: ignore[arg-type]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Postgres:
    """A PostgreSQL server in a temporary folder (trust authentication on 127.0.0.1 only); .url(db) a database's URL."""

    def __init__(self):
        self.bin, self.port = _pg_bin(), _free_port()
        self.root = Path(tempfile.mkdtemp(prefix="simucal-pg-"))
        self.data, self.log = self.root / "data", self.root / "server.log"
        self.as_user = ["runuser", "-u", "postgres", "--"] if os.geteuid() == 0 else []  # it refuses to run as root
        if self.as_user:
            shutil.chown(self.root, "postgres")
        self._run("initdb", "-D", self.data, "-A", "trust", "-U", "simucal", "--no-sync", "-E", "UTF8")
        self._run("pg_ctl", "-D", self.data, "-l", self.log, "-w", "-t", "60", "start", "-o",
                  f"-p {self.port} -k {self.root} -c listen_addresses=127.0.0.1 -c fsync=off")
        self.count = 0

    def _run(self, tool, *args):
        res = subprocess.run([*self.as_user, str(self.bin / tool), *map(str, args)], capture_output=True, text=True)
        assert res.returncode == 0, (tool, res.stdout[-2000:], res.stderr[-2000:])

    def url(self, password: str | None = None) -> str:
        """A new empty database's URL (password: put in the URL; trust authentication ignores it)."""
        import psycopg
        self.count += 1
        name = f"store{self.count}"
        with psycopg.connect(f"host=127.0.0.1 port={self.port} user=simucal dbname=postgres", autocommit=True) as c:
            c.execute(f"CREATE DATABASE {name}")
        return f"postgresql://simucal{':' + password if password else ''}@127.0.0.1:{self.port}/{name}"

    def stop(self):
        self._run("pg_ctl", "-D", self.data, "-m", "fast", "-w", "stop")
        shutil.rmtree(self.root, ignore_errors=True)


def base_calibration(folder: Path) -> Path:
    """One calibration file of a simulated turntable set (the default unit, seed 1)."""
    import simucal
    path = folder / "base.json"
    simucal.save(path, simucal.calibrate(simucal.simulate(seed=1)))
    return path


def unit_files(base: Path, folder: Path, units: int, visits: int, drifting=(), drift_std: float = 12.0,
               seed: int = 0, prefix: str = "SN") -> dict[str, list[Path]]:
    """{serial: its calibration files, visit by visit}: each unit's parameters its own draw about the base's
    (the file's covariance), each visit another draw about the unit's; the units in `drifting` move DRIFT_PARAM
    by drift_std of its std at each visit."""
    rng = np.random.default_rng(seed)
    text = base.read_text()
    out: dict[str, list[Path]] = {}
    folder.mkdir(parents=True, exist_ok=True)
    for u in range(units):
        serial = f"{prefix}-{u:04d}"
        unit_offset = {s: _draw(b, rng, 3.0) for s, b in calibration.loads(text, base).blocks()}
        for v in range(visits):
            cal = calibration.loads(text, base)
            cal.layout["unit_serial"] = serial
            for s, b in cal.blocks():
                for n, d in _draw(b, rng).items():
                    b.params[n] += unit_offset[s][n] + d
            if u in drifting:
                sensor, name = DRIFT_PARAM.split(".")
                block = getattr(cal, sensor)
                block.params[name] += v * drift_std * block.std[name]
            for _, b in cal.blocks():
                _follow_parameters(b)
            path = folder / f"{serial}_{v}.json"
            calibration.save(path, cal)
            out.setdefault(serial, []).append(path)
    return out


def _follow_parameters(block) -> None:
    """The block's M and bias from its parameters, as the methods write them (M(p) C, bias(p)): a file whose
    parameters were drawn stays one calibration in every vocabulary."""
    from simucal.fit.augmented import AugmentedModel
    model = AugmentedModel(block.model, block.library_effects())
    M, bias = model.matrix_and_bias([block.params[n] for n in model.params])
    block.M, block.bias = np.asarray(M) @ block.C, np.asarray(bias)


def _draw(block, rng, scale: float = 1.0) -> dict[str, float]:
    """A draw of the block's parameters' errors from its covariance (times scale)."""
    cov = block.details["covariance"]
    x = rng.multivariate_normal(np.zeros(len(cov["names"])), np.asarray(cov["matrix"], float)) * scale
    return {n: float(v) for n, v in zip(cov["names"], x) if n in block.params}
