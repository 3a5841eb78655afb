"""Writing files so that a failure never leaves a half-written one behind."""

from __future__ import annotations

import os
import re
import shutil
import stat
import tempfile
from pathlib import Path


def write_atomic(path: str | Path, data: bytes | str) -> bool:
    """Write ``data`` to ``path`` through a temporary file and a rename.

    Returns False (and leaves the file alone, keeping its mtime) when the
    content is already the same, so make and CMake do not rebuild needlessly.
    A file that exists keeps its mode; a new one gets the user's umask, as
    ``open()`` would give it (mkstemp alone would leave it ``-rw-------``).
    """
    p = Path(path)
    raw = data.encode("utf-8") if isinstance(data, str) else data
    try:
        if p.read_bytes() == raw:
            return False
    except OSError:
        pass
    try:
        mode = stat.S_IMODE(p.stat().st_mode)
    except OSError:
        mode = 0o666 & ~current_umask()
    p.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=p.parent)
    try:
        os.fchmod(fd, mode)
        with os.fdopen(fd, "wb") as f:
            f.write(raw)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, p)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return True


def current_umask() -> int:
    """The process's umask (read from /proc where it can be, without changing it)."""
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    umask = os.umask(0o022)  # no /proc: set and restore (not thread-safe, but only then)
    os.umask(umask)
    return umask


MANIFEST = ".hfsmc-manifest"
_RENAME_EXCHANGE = 2
_AT_FDCWD = -100


def _exchange(a: Path, b: Path) -> bool:
    """Swap two directories in one step (Linux renameat2); False when not possible here."""
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        fn = libc.renameat2
    except (OSError, AttributeError):
        return False
    rc = fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE)
    return bool(rc == 0)


def _clean_stale_stages(target: Path) -> None:
    """Remove staging folders left beside ``target`` by builds that were killed.

    A stage is named ``.NAME.PID.XXXX.new`` after the process that made it; one
    whose process is gone is removed. A live build's stage is left alone.
    """
    # mkdtemp's random part has no dot: `.v.2.PID.x.new` (a stage of `v.2`) is not one of `v`.
    pattern = re.compile(rf"\.{re.escape(target.name)}\.(\d+)\.[a-z0-9_]+\.new")
    try:
        entries = list(target.parent.iterdir())
    except OSError:
        return
    for entry in entries:
        m = pattern.fullmatch(entry.name)
        if m is None or int(m[1]) == os.getpid():
            continue
        try:
            os.kill(int(m[1]), 0)
        except ProcessLookupError:
            shutil.rmtree(entry, ignore_errors=True)
        except (PermissionError, OverflowError):
            pass


def _old_manifest(target: Path) -> list[str]:
    try:
        return (target / MANIFEST).read_text("utf-8").splitlines()
    except OSError:
        return []


def write_tree(target: str | Path, files: dict[str, bytes], executable: frozenset[str]
               = frozenset()) -> list[str]:
    """Make folder ``target`` hold ``files`` (relative path -> bytes); the changed paths.

    The new folder is staged beside the old one and swapped in with one atomic
    exchange, so a build killed at any moment leaves either the old component
    or the new one, never a mix.  Files whose bytes did not change are hard
    links to the old ones (same mtime: make and CMake see no change); files
    hfsmc did not write (a CMake build folder, a user's notes) are moved over.
    Where the exchange is not available, each file is replaced atomically.
    """
    target = Path(target)
    old = set(_old_manifest(target)) if target.is_dir() else set()
    changed = []
    for rel, data in files.items():
        try:
            if (target / rel).read_bytes() == data:
                continue
        except OSError:
            pass
        changed.append(rel)
    stale = sorted(old - set(files))
    _clean_stale_stages(target)
    if target.is_dir() and not changed and not stale and (target / MANIFEST).is_file():
        return []
    target.parent.mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(prefix=f".{target.name}.{os.getpid()}.", suffix=".new",
                                  dir=target.parent))
    stage.chmod(0o777 & ~current_umask())  # mkdtemp's 0700 would become the component folder's mode
    try:
        for rel, data in files.items():
            dest = stage / rel
            dest.parent.mkdir(parents=True, exist_ok=True)
            if rel not in changed:
                os.link(target / rel, dest)
                continue
            dest.write_bytes(data)
            if rel in executable:
                dest.chmod(0o755)
        (stage / MANIFEST).write_text("".join(f"{r}\n" for r in sorted(files)), "utf-8")
        if not target.exists():
            os.rename(stage, target)
            return changed
        if not _exchange(stage, target):
            shutil.rmtree(stage)
            for rel in changed:
                write_atomic(target / rel, files[rel])
                if rel in executable:
                    (target / rel).chmod(0o755)
            for rel in stale:
                (target / rel).unlink(missing_ok=True)
            write_atomic(target / MANIFEST, "".join(f"{r}\n" for r in sorted(files)))
            return changed
        # `stage` now holds the old folder: move what hfsmc did not write back in.
        for entry in stage.iterdir():
            rel = entry.name
            if rel == MANIFEST or rel in old or any(f.startswith(rel + "/") for f in old):
                continue
            if not (target / rel).exists():
                os.rename(entry, target / rel)
    finally:
        shutil.rmtree(stage, ignore_errors=True)
    return changed
