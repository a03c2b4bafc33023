"""Where a SQLite store's file lives (simucal/store/sqlite_file.py): on a network file system the rollback
journal, not the write-ahead log whose shared memory does not hold between machines; in a folder this user
cannot write, read only (a WAL store read as immutable, nothing written beside it) and recording refused in
one line; each through the command line in a fresh process, as a station runs it."""
import subprocess
import sys
from pathlib import Path

import pytest

import simucal
from simucal.errors import SimucalError
from simucal.store import sqlite_file
from simucal.store.sqlite_file import filesystem_type


def _journal(path: Path) -> str:
    """The file's journal as its header says (bytes 18 and 19: 1 rollback, 2 write-ahead log)."""
    header = path.read_bytes()[:20]
    return {(1, 1): "rollback", (2, 2): "wal"}[(header[18], header[19])]


def _two_records(store: Path) -> None:
    st = simucal.Store(store)
    for seed in (1, 2):
        st.add(simucal.calibrate(simucal.simulate(seed=seed)), serial=f"SN-{seed}", time=f"2026-0{seed}-01")
    st.close()


def test_the_mount_table_gives_the_longest_mount_point_above_a_path(tmp_path):
    mounts = tmp_path / "mounts"
    mounts.write_text("/dev/sda1 / ext4 rw 0 0\nserver:/lab /mnt/lab nfs4 rw 0 0\n"
                      "//nas/x /mnt/lab/smb\\040share cifs rw 0 0\ntmpfs /mnt/labx tmpfs rw 0 0\n")
    assert filesystem_type(Path("/mnt/lab/a/lab.db"), mounts) == "nfs4"
    assert filesystem_type(Path("/mnt/lab/smb share/lab.db"), mounts) == "cifs"
    assert filesystem_type(Path("/mnt/labx/lab.db"), mounts) == "tmpfs"  # not /mnt/lab's: a name, not a prefix
    assert filesystem_type(Path("/home/lab.db"), mounts) == "ext4"
    assert filesystem_type(Path("/x"), tmp_path / "none") is None  # no table (not Linux)


def test_a_store_on_a_network_file_system_keeps_a_rollback_journal(tmp_path, monkeypatch):
    """The mount table says the store's folder is NFS: the store is made with the rollback journal and a WAL
    store found there is turned to it; on a local disk the write-ahead log."""
    local = tmp_path / "local.db"
    _two_records(local)
    assert _journal(local) == "wal"
    mounts = tmp_path / "mounts"
    mounts.write_text(f"/dev/sda1 / ext4 rw 0 0\nserver:/lab {tmp_path} nfs4 rw 0 0\n")
    monkeypatch.setattr(sqlite_file, "MOUNTS", mounts)
    shared = tmp_path / "shared.db"
    _two_records(shared)
    assert _journal(shared) == "rollback" and not list(tmp_path.glob("shared.db-*"))
    assert len(simucal.Store(local).records()) == 2 and _journal(local) == "rollback"  # a WAL store found there
    assert list(simucal.Store(shared).records()["serial"]) == ["SN-1", "SN-2"]


def test_a_store_in_a_read_only_folder_is_read_and_never_written(tmp_path, monkeypatch):
    """A folder this user cannot write (the suite may run as root, whom permissions do not bind: the check is
    made to say so): the store is read as immutable, nothing is written beside it, and recording is refused."""
    store = tmp_path / "lab.db"
    _two_records(store)
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    monkeypatch.setattr(sqlite_file, "writable", lambda path: False)
    st = simucal.Store(store)
    assert list(st.records()["serial"]) == ["SN-1", "SN-2"] and len(st.history("SN-1")["records"]) == 1
    with pytest.raises(SimucalError, match=f"lab.db: the store's file or its folder {tmp_path} is read-only for "
                                           "this user.*record into a store in a folder you can write"):
        st.add(simucal.calibrate(simucal.simulate(seed=3)), serial="SN-3")
    st.close()
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before  # no journal, no -shm, the file as it was


def test_the_store_commands_run_in_a_fresh_process(tmp_path):
    """history and certificate --record each in a process of its own, as a station runs them (in the suite's
    process an earlier test has imported what a fresh one must import itself)."""
    store = tmp_path / "lab.db"
    _two_records(store)
    for args in (["history", "SN-1", "--store", store, "-o", tmp_path / "h.json"],
                 ["certificate", "--store", store, "--record", 2, "-o", tmp_path / "c.html"]):
        r = subprocess.run([sys.executable, "-m", "simucal", *map(str, args)], capture_output=True, text=True,
                           cwd=tmp_path)
        assert r.returncode == 0, r.stdout + r.stderr
    assert "unit SN-2" in (tmp_path / "c.html").read_text() and (tmp_path / "h.json").stat().st_size > 100
