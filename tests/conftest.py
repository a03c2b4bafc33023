import os
import shutil
import tempfile
from pathlib import Path

import pytest

# user models derived by the tests go to a cache of their own, never the user's: one for the run, made by the
# first process that loads this file (pytest-xdist's controller) and inherited by its workers, so that each
# library and derived model is built once, as the processes of one user share ~/.cache/simucal
MADE_CACHE = None  # the folder this process made: it removes it when the run ends
if "SIMUCAL_TEST_CACHE" not in os.environ:
    os.environ["SIMUCAL_TEST_CACHE"] = MADE_CACHE = tempfile.mkdtemp(prefix="simucal-test-cache-")
os.environ["SIMUCAL_CACHE"] = os.environ["SIMUCAL_TEST_CACHE"]
# one BLAS thread in each test process and the processes it starts (set before numpy loads OpenBLAS): the suite
# runs on two processes (-n 2), so a BLAS's second thread finds no free core and spins (a planted-effect loop
# test 5.6-8.0 s with one thread, 11.8-15.9 s with two, alone at load 1.5-3)
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from simucal.turntable.simulate import Scenario, write  # noqa: E402 (after the cache is set)

REPOSITORY = pytest.StashKey[dict]()


ROOT = Path(__file__).resolve().parents[1]
TOOL_CACHES = {".git", "__pycache__", ".pytest_cache", ".hypothesis", ".mypy_cache", ".ruff_cache"}


def _repository_files() -> dict:
    """{path: (size, mtime)} of every file in the repository's tree but the tools' caches (bytecode, git's,
    pytest's, the linters') and virtual environments: what a test may neither write nor remove."""
    files = {}
    for folder, subfolders, names in os.walk(ROOT):
        subfolders[:] = [d for d in subfolders if d not in TOOL_CACHES and not d.endswith(".egg-info")
                         and not d.startswith(".venv")]
        for name in names:
            st = os.lstat(os.path.join(folder, name))
            files[os.path.relpath(os.path.join(folder, name), ROOT)] = (st.st_size, st.st_mtime_ns)
    return files


def pytest_sessionstart(session):
    if not hasattr(session.config, "workerinput"):  # the controller, once for the run
        session.config.stash[REPOSITORY] = _repository_files()


def pytest_sessionfinish(session, exitstatus):
    """The guard of isolated tests: the run fails where the repository's tree changed under it."""
    before = session.config.stash.get(REPOSITORY, None)
    if before is None:
        return
    after = _repository_files()
    changed = sorted(p for p in before.keys() | after.keys() if before.get(p) != after.get(p))
    if changed:
        session.config.get_terminal_writer().line(
            f"the tests wrote, changed or removed files in the repository's tree ({ROOT}): {', '.join(changed[:10])}"
            f"{' ...' if len(changed) > 10 else ''}; a test writes only under its tmp_path", red=True)
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


@pytest.fixture(autouse=True)
def _a_working_folder_of_its_own(tmp_path_factory, monkeypatch):
    """Every test starts in an empty folder of its own: none reads or writes the folder pytest was started in
    (a fresh clone's README runs the demo into ./out before the tests)."""
    monkeypatch.chdir(tmp_path_factory.mktemp("cwd"))


def pytest_unconfigure(config):
    """The run's test cache removed by the process that made it (tens of MB of libraries a run)."""
    if MADE_CACHE:
        shutil.rmtree(MADE_CACHE, ignore_errors=True)


@pytest.fixture(scope="session")
def audit_report():
    """The paper's audit with the section-4 term-by-term check (SymPy, seconds): shared by its tests."""
    from simucal.derive.audit import run_audit
    from simucal.report.paper_claims import section4_values
    return run_audit(values=section4_values())


@pytest.fixture(scope="session")
def paper_set(tmp_path_factory):
    """The paper scenario, one seed, shared by the calibration tests."""
    folder = tmp_path_factory.mktemp("paper")
    truth = write(folder, Scenario(), seed=3)
    return folder, truth


@pytest.fixture(scope="module")
def dask_cluster():
    """The address of a Dask LocalCluster (2 single-threaded worker processes on 127.0.0.1) shared by a
    module's tests that check a result on Dask, not the cluster's start: each start costs 1-1.5 s of CPU
    (2 worker processes importing distributed). One a module, not one for the session: idle, its workers
    took 14 s of CPU over a run of the suite. tests/test_security.py still starts one through
    `scheduler="processes"`, the path a user's --scheduler processes takes."""
    from distributed import LocalCluster
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                      dashboard_address=None) as cluster:
        yield cluster.scheduler_address


TESTS = Path(__file__).resolve().parent


def _shared_fixtures(item):
    """The fixtures of this suite that the item uses and that are built once for many tests: a module-scoped
    one named by its module, a session-scoped one by its name alone (one value for the whole run)."""
    for name in item.fixturenames:
        for fixture in item._fixtureinfo.name2fixturedefs.get(name, ()):
            if fixture.scope in ("module", "session") and Path(fixture.func.__code__.co_filename).parent == TESTS:
                yield f"{item.module.__name__}.{name}" if fixture.scope == "module" else name


SLOW_FIXTURES = {"audit_report", "site", "pages", "lot"}  # shared, and seconds to build: their tests are slow


@pytest.hookimpl(tryfirst=True)  # before pytest-xdist's, which reads the marks into each test's id
def pytest_collection_modifyitems(config, items):
    """The suite runs on two processes with `--dist loadgroup` (README): each test goes to whichever process is
    free, so both finish together (with --dist loadfile a whole file went to one, and the run waited on the
    last heavy file), except that the tests sharing a fixture built once for many (a module's or the session's,
    and those linked to them through another such fixture) are one group, run on one process, so that no
    such fixture is built twice."""
    parent = {}

    def root(key):
        while parent.setdefault(key, key) != key:
            key = parent[key]
        return key
    shared = {item: list(_shared_fixtures(item)) for item in items}
    for keys in shared.values():
        for key in keys[1:]:
            parent[root(key)] = root(keys[0])
    for item, keys in shared.items():
        if keys:
            item.add_marker(pytest.mark.xdist_group(root(keys[0])))
        if SLOW_FIXTURES & set(item.fixturenames):
            item.add_marker(pytest.mark.slow)
