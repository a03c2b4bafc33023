"""Simucal runs only code the user built. Code another user planted in the cache never
runs: a library built from a model's own C plus a constructor that writes a marker file is put
where simucal's build was (the attack of the issue: the calibration comes out the same, so only
the marker shows it ran), and simucal loads it in a process of its own (dlopen would return a
library this one already holds). Model files run only where named; a scheduler's address is
reached with Dask's TLS configuration; the LocalCluster listens on localhost alone."""
import json
import os
import subprocess
import sys
import warnings
from pathlib import Path

import pytest
from click.testing import CliRunner

from simucal.cli import main
from simucal.fit import augmented, catalog
from simucal.fit.models import generated_dir, load_builtin, manifest
from simucal.io import cache
from simucal.io.cache import compile_c, compiler
from simucal.sweeps import map_tasks

PLANT = '\n#include <stdio.h>\n__attribute__((constructor)) static void planted(void) {{ ' \
        'FILE *f = fopen("{marker}", "w"); if (f) {{ fputs("planted code ran", f); fclose(f); }} }}\n'
LOAD = "from simucal.fit.models import load_builtin; print(load_builtin('acc_baseline').backend)"


@pytest.fixture
def built(tmp_path, monkeypatch):
    """A cache holding simucal's build of acc_baseline; returns (library, the planted library, marker)."""
    assert compiler() is not None, "these tests need the C compiler the CI has"
    monkeypatch.setenv("SIMUCAL_CACHE", str(tmp_path / "cache"))
    source = (generated_dir() / manifest()["models"]["acc_baseline"]["c_file"]).read_text()
    lib = compile_c("acc_baseline", source)
    marker = tmp_path / "planted.txt"
    planted = tmp_path / "planted.so"
    subprocess.run([compiler(), "-shared", "-fPIC", "-x", "c", "-", "-o", str(planted), "-lm"], check=True,
                   input=source + PLANT.format(marker=marker), text=True)
    return lib, planted, marker


def _load_elsewhere():
    r = subprocess.run([sys.executable, "-c", LOAD], capture_output=True, text=True, env=os.environ)
    assert r.returncode == 0, r.stderr
    return r.stdout.strip(), r.stderr


@pytest.mark.slow
def test_the_planted_library_runs_when_loaded_so_its_absence_below_means_something(built):
    lib, planted, marker = built
    import ctypes
    ctypes.CDLL(str(planted))
    assert marker.read_text() == "planted code ran"


@pytest.mark.slow
def test_the_cache_is_made_for_its_user_alone(built):
    lib, _, _ = built
    assert lib.parent == cache.cache_dir() and os.stat(lib.parent).st_mode & 0o777 == 0o700
    assert (lib.parent / (lib.name + ".sha256")).read_text().strip() == cache.sha256_of(lib)


@pytest.mark.slow
def test_a_cache_writable_by_others_loads_nothing_from_it(built):
    """The issue's case: a cache of mode 777, a planted library and even its sha256 rewritten."""
    lib, planted, marker = built
    lib.write_bytes(planted.read_bytes())
    cache.record(lib)
    os.chmod(lib.parent, 0o777)
    backend, err = _load_elsewhere()
    assert backend == "numpy" and not marker.exists()
    assert f"{lib.parent} (mode 0777) is writable by group or others" in err and "chmod 700" in err


@pytest.mark.slow
def test_a_library_writable_by_others_is_not_loaded(built):
    lib, planted, marker = built
    lib.write_bytes(planted.read_bytes())
    cache.record(lib)
    os.chmod(lib, 0o777)
    backend, err = _load_elsewhere()
    assert backend == "numpy" and not marker.exists()
    assert f"{lib} (mode 0777) is writable by group or others" in err and f"chmod go-w {lib}" in err


@pytest.mark.slow
def test_a_library_changed_after_its_build_is_rebuilt_not_run(built):
    lib, planted, marker = built
    genuine = cache.sha256_of(lib)
    lib.write_bytes(planted.read_bytes())
    backend, err = _load_elsewhere()
    assert backend == "casadi-c" and not marker.exists()
    assert f"{lib} changed after its build" in err and "rebuilt" in err
    assert cache.sha256_of(lib) == genuine


@pytest.mark.slow
def test_a_cache_of_another_user_loads_nothing(built, monkeypatch):
    """Tests run as root, whose files these are: another user is played by the uid simucal sees."""
    lib, planted, marker = built
    lib.write_bytes(planted.read_bytes())
    cache.record(lib)
    monkeypatch.setattr(os, "getuid", lambda: 4242)
    with pytest.warns(cache.CacheWarning, match=rf"{lib.parent} \(mode 0700\) belongs to uid \d+, not to you"):
        model = load_builtin("acc_baseline")
    assert model.backend == "numpy" and not marker.exists()


@pytest.mark.slow
def test_the_warning_is_one_line_on_the_command_line(built, tmp_path):
    lib, _, _ = built
    os.chmod(lib.parent, 0o777)
    f = tmp_path / "mine.py"  # a user model: refused with the fix, its file never run
    f.write_text(f"open({str(tmp_path / 'ran.txt')!r}, 'w')\n")
    r = CliRunner().invoke(main, ["derive", "--model", str(f)])
    lines = r.stderr.strip().splitlines()
    assert r.exit_code == 2 and len(lines) == 1 and "chmod 700" in lines[0] and "0777" in lines[0], r.stderr
    assert not (tmp_path / "ran.txt").exists()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        compile_c("acc_baseline", (lib.with_suffix(".c")).read_text())
    from simucal.cli.common import _one_line
    w = caught[-1]
    assert _one_line(w.message, w.category, w.filename, w.lineno).count("\n") == 1


@pytest.mark.slow
def test_the_trusted_cache_is_read_only_and_checked(built, tmp_path, monkeypatch):
    """A lab's cache (SIMUCAL_TRUSTED_CACHE): loaded where it is root's or the user's and writable
    by neither group nor others, never written; refused otherwise."""
    lib, planted, marker = built
    monkeypatch.setenv("SIMUCAL_TRUSTED_CACHE", str(lib.parent))
    monkeypatch.setenv("SIMUCAL_CACHE", str(tmp_path / "mine"))
    os.chmod(lib.parent, 0o755)  # as an administrator leaves it: readable by all
    assert compile_c("acc_baseline", lib.with_suffix(".c").read_text()) == lib
    assert not (tmp_path / "mine").exists()
    lib.write_bytes(planted.read_bytes())
    cache.record(lib)
    os.chmod(lib.parent, 0o775)
    backend, err = _load_elsewhere()
    assert backend == "numpy" and not marker.exists() and "SIMUCAL_TRUSTED_CACHE" in err


def test_a_derived_model_in_a_cache_of_others_is_refused(tmp_path, monkeypatch):
    monkeypatch.setenv("SIMUCAL_CACHE", str(tmp_path / "cache"))
    key = "k" * 20
    folder = tmp_path / "cache" / "models" / key
    folder.mkdir(parents=True)
    marker = tmp_path / "ran.txt"
    (folder / "acc_mine.py").write_text(f"open({str(marker)!r}, 'w')\n")
    (folder / "acc_mine.c").write_text("")
    (folder.parent / "index.json").write_text(json.dumps({"acc_mine": {"key": key, "source": "mine.py"}}))
    os.chmod(folder, 0o770)
    with pytest.raises(cache.UntrustedCache, match=rf"{folder} \(mode 0770\).*chmod 700 {folder}"):
        catalog.load("acc_mine")
    assert not marker.exists()


def test_simucal_runs_no_model_file_it_finds(tmp_path, monkeypatch):
    """The one model file simucal writes itself (a built-in model with effects) is written again
    where the cache holds other bytes, before it is derived."""
    monkeypatch.setenv("SIMUCAL_CACHE", str(tmp_path / "cache"))
    seen = []
    monkeypatch.setattr(augmented, "derive_model_file", lambda p: seen.append(Path(p).read_text()))
    monkeypatch.setattr(augmented, "load", lambda name: name)
    name = "acc_baseline_with_acc_quadratic_z"
    augmented._derive("acc_baseline", ("acc.quadratic.z",))
    planted = cache.cache_dir() / "augmented" / f"{name}.py"
    planted.write_text("open('ran.txt', 'w')\n")
    augmented._derive("acc_baseline", ("acc.quadratic.z",))
    assert seen[0] == seen[1] == planted.read_text() and "open(" not in seen[1]


def test_a_tls_address_without_credentials_is_refused_naming_the_configuration():
    from simucal.errors import CalibrationError
    with pytest.raises(CalibrationError, match=r"tls://127.0.0.1:1: .*distributed\.comm\.tls\.ca-file"):
        map_tasks(pow, [(2, 3)], "tls://127.0.0.1:1")


def test_a_tls_scheduler_is_reached_with_the_credentials_of_dasks_configuration(tmp_path):
    import dask.config
    from distributed import LocalCluster
    from distributed.security import Security
    cert, key = tmp_path / "cert.pem", tmp_path / "key.pem"
    subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", key, "-out", cert,
                    "-days", "1", "-subj", "/CN=localhost"], check=True, capture_output=True)
    sec = Security(tls_ca_file=str(cert), tls_scheduler_cert=str(cert), tls_scheduler_key=str(key),
                   tls_worker_cert=str(cert), tls_worker_key=str(key), tls_client_cert=str(cert),
                   tls_client_key=str(key), require_encryption=True)
    with LocalCluster(n_workers=1, processes=False, protocol="tls://", host="127.0.0.1", security=sec,
                      dashboard_address=None) as cluster:
        assert cluster.scheduler_address.startswith("tls://127.0.0.1:")
        with dask.config.set({"distributed.comm.tls.ca-file": str(cert), "distributed.comm.tls.client.cert": str(cert),
                              "distributed.comm.tls.client.key": str(key)}):
            assert map_tasks(pow, [(2, 3), (3, 2)], cluster.scheduler_address) == [8, 9]


def _addresses(_):
    from distributed import get_worker
    worker = get_worker()
    return worker.address, worker.scheduler.address


@pytest.mark.slow
def test_the_local_cluster_listens_on_localhost_alone():
    for worker, scheduler in map_tasks(_addresses, [(0,), (1,)], "processes"):
        assert worker.startswith("tcp://127.0.0.1:") and scheduler.startswith("tcp://127.0.0.1:"), (worker, scheduler)


@pytest.mark.slow
def test_a_user_model_in_the_trusted_cache_is_used_by_name_and_its_file_never_run_again(tmp_path, monkeypatch):
    f, marks = tmp_path / "mine.py", tmp_path / "ran.txt"
    f.write_text("from simucal.derive.models.baseline import ACC_BASELINE\n"
                 "from simucal.derive.models.effects import acc_quadratic\n"
                 f"open({str(marks)!r}, 'a').write('ran\\n')\n"
                 "MODELS = [ACC_BASELINE.with_terms('acc_lab', [acc_quadratic('z')])]\n")
    monkeypatch.setenv("SIMUCAL_CACHE", str(tmp_path / "lab"))  # the administrator fills it
    assert catalog.derive_model_file(f) == (["acc_lab"], True)
    monkeypatch.setenv("SIMUCAL_TRUSTED_CACHE", str(tmp_path / "lab"))
    monkeypatch.setenv("SIMUCAL_CACHE", str(tmp_path / "mine"))
    catalog.load.cache_clear()
    assert catalog.load("acc_lab").source == str(f)
    assert catalog.derive_model_file(f) == (["acc_lab"], False)
    assert marks.read_text() == "ran\n"
    os.chmod(tmp_path / "lab" / "models", 0o777)
    catalog.load.cache_clear()
    with pytest.raises(cache.UntrustedCache, match="SIMUCAL_TRUSTED_CACHE"):
        catalog.load("acc_lab")


def _add_entries(worker, n):
    from simucal.fit import catalog
    for i in range(n):
        catalog._add_to_index({f"m{worker}_{i}": {"key": f"k{worker}_{i}", "source": "test"}})


@pytest.mark.slow
def test_processes_adding_models_to_one_cache_lose_no_entry(tmp_path, monkeypatch):
    """index.json is read, changed and written under a lock: four processes adding 40 entries each to one
    cache at once (Dask workers deriving model files) keep all 160 (without the lock most were lost)."""
    import multiprocessing
    from simucal.io import cache
    monkeypatch.setenv("SIMUCAL_CACHE", str(tmp_path / "cache"))  # the spawned processes inherit it
    cache.own_folder("models")
    procs = [multiprocessing.get_context("spawn").Process(target=_add_entries, args=(w, 40)) for w in range(4)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(120)
    assert [p.exitcode for p in procs] == [0] * 4
    assert len(json.loads((tmp_path / "cache" / "models" / "index.json").read_text())) == 160


def test_a_cache_path_that_is_a_file_is_named_and_the_numpy_modules_run(tmp_path, paper_set):
    """SIMUCAL_CACHE naming a file: a warning naming the variable and the fix, the work done by the
    uncompiled modules; was FileExistsError, 'a bug in simucal'."""
    (tmp_path / "afile").write_text("")
    r = subprocess.run([sys.executable, "-m", "simucal", "calibrate", str(paper_set[0]), "-o",
                        str(tmp_path / "c.json")],
                       capture_output=True, text=True, env={**os.environ, "SIMUCAL_CACHE": str(tmp_path / "afile")})
    assert r.returncode == 0, r.stderr
    assert "is a file, not a folder" in r.stderr and "set SIMUCAL_CACHE to a folder" in r.stderr


def test_a_cache_inside_the_input_is_refused_and_nothing_written_there(tmp_path, monkeypatch):
    """Compiled libraries are never written into a user's data: a cache inside the set read."""
    from cli_helpers import refused
    from simucal.turntable.simulate import Scenario, write
    write(tmp_path / "set", Scenario(), seed=1)
    before = sorted(p.name for p in (tmp_path / "set").iterdir())
    monkeypatch.setenv("SIMUCAL_CACHE", str(tmp_path / "set" / "cache"))
    refused(CliRunner().invoke(main, ["calibrate", str(tmp_path / "set"), "-o", str(tmp_path / "c.json")]),
            "SIMUCAL_CACHE=", "lies inside the input", "set SIMUCAL_CACHE to a folder outside it")
    assert sorted(p.name for p in (tmp_path / "set").iterdir()) == before
