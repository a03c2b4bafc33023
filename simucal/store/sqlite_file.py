"""How a SQLite store's file is opened, by where it lives and what this user may do there.

- A local folder this user can write: the write-ahead log (journal_mode=WAL), so that a station reading
  (history, lot) neither waits for a writer nor blocks one.
- A network file system (NFS, SMB/CIFS, sshfs, ...): WAL keeps its index in shared memory, which does not
  work between machines (SQLite's documentation: "WAL does not work over a network filesystem"), so the
  rollback journal (journal_mode=DELETE), locked through the file system's own locks.
- A file, or a folder, this user cannot write (read-only media, another's folder): read only
  (SQLite's mode=ro); a WAL store whose shared-memory file (-shm) is not there and cannot be made is read
  as immutable, a snapshot (a station writing it meanwhile is not seen). Recording into it is refused in
  one line naming the fix.
"""
from __future__ import annotations

import os
from pathlib import Path
from urllib.parse import quote

from simucal.errors import StoreError

# file system types (as /proc/mounts names them) on which WAL's shared memory does not hold between machines
NETWORK_FS = frozenset({"nfs", "nfs4", "cifs", "smb3", "smbfs", "fuse.sshfs", "9p", "afs", "ceph", "glusterfs",
                        "fuse.glusterfs", "lustre", "gpfs", "beegfs", "davfs", "fuse.rclone", "fuse.s3fs"})
MOUNTS = Path("/proc/mounts")


def filesystem_type(path: Path, mounts: Path | None = None) -> str | None:
    """The type of the file system path lies on: the longest mount point above it in the mount table
    (mounts, default Linux's /proc/mounts); None where there is no such table."""
    try:
        table = (mounts or MOUNTS).read_text()
    except OSError:
        return None
    where, best, kind = str(path.resolve()), "", None
    for line in table.splitlines():
        fields = line.split()
        if len(fields) < 3:
            continue
        point = fields[1].replace("\\040", " ")  # the table writes a space in a mount point as \040
        if (where == point or where.startswith(point.rstrip("/") + "/")) and len(point) > len(best):
            best, kind = point, fields[2]
    return kind


def writable(path: Path) -> bool:
    """Whether this user can write the store: its folder (SQLite writes its journal beside the file) and the
    file where it exists."""
    return os.access(path.parent, os.W_OK) and (not path.exists() or os.access(path, os.W_OK))


def _in_wal_mode(path: Path) -> bool:
    """The file's header says write-ahead log (bytes 18 and 19 are 2: SQLite's file format)."""
    with path.open("rb") as f:
        header = f.read(20)
    return len(header) == 20 and header[18] == 2 and header[19] == 2


def how_to_open(path: Path, shown: str, write: bool) -> tuple[str, str | None]:
    """(the SQLAlchemy URL, the journal mode to set; None: read only, set nothing) of the store file at path
    (module doc); shown: the store as messages name it. Writing where this user cannot is refused."""
    if not writable(path):
        if write:
            raise StoreError(f"{shown}: the store's file or its folder {path.parent} is read-only for this user, "
                             "and recording writes both (SQLite's journal lies beside the file); record into a "
                             "store in a folder you can write, or ask for write access")
        shm = path.with_name(path.name + "-shm")
        immutable = path.is_file() and _in_wal_mode(path) and not shm.exists()
        return f"sqlite:///file:{quote(str(path))}?mode=ro{'&immutable=1' if immutable else ''}&uri=true", None
    mode = "DELETE" if filesystem_type(path) in NETWORK_FS else "WAL"
    return f"sqlite:///{path}", mode
