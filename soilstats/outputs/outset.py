"""An output set is one unit: a command's files in ``--out`` are replaced all at once or not at all.

The write protocol of every command with ``--out DIR`` (:func:`output_set`, entered by the
command line around the whole run, docs/conventions.md "Output sets"):

1. **Lock.** ``.DIR.soilstats-lock`` beside DIR is created exclusively (``O_EXCL``) and holds
   the pid, host, command and start time of the run. A second run on the same DIR refuses
   (exit 2) naming the first; a lock whose process is gone (a killed run) is stale: it is
   removed and named in a warning.
2. **Stage.** A staging folder ``.DIR.soilstats-stage-XXXX`` beside DIR starts as a copy of
   DIR made of hard links (no data copied); every writer of :mod:`soilstats.outputs.files`
   writes into it instead of DIR (:func:`~soilstats.outputs.files.staged`). The
   no-overwrite rule is judged there, so it sees what DIR held when the run started.
3. **Commit.** When the run ends without an error, the existence of each file it wrote is
   checked again in DIR (a file that appeared since, without ``--overwrite``, is refused),
   files others added to DIR meanwhile are linked into the stage, and the stage is swapped
   with DIR in one atomic ``renameat2(RENAME_EXCHANGE)`` (Linux; elsewhere two renames,
   which the next run completes if interrupted between them). A run that wrote nothing
   leaves DIR as it was (and makes no folder).
4. **Failure.** An error, ``KeyboardInterrupt`` or a full disk removes the stage: DIR holds
   the whole old set. A killed run leaves its stage and lock; the next run on DIR removes
   them and says so, and removes (and names) stray temporaries ``.NAME.XXXXXXXXXXXX.tmp…``
   left in DIR by older versions.

When DIR holds the working folder (``--out .``), swapping it would strand the shell in a
removed folder, and when DIR's parent cannot be written no stage can sit beside it: then the
files are moved from the stage into DIR one by one at the end (the old in-place behaviour,
each file still atomic).
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import json
import os
import re
import shutil
import socket
import sys
import tempfile
import time
import warnings
from collections.abc import Iterator
from pathlib import Path

from ..errors import InputError, SoilstatsWarning
from . import files

__all__ = ["lock_path", "output_set"]

#: A temporary file of :func:`soilstats.outputs.files._temporary`: ``.NAME.HEX12.tmp[.ext]``.
_TEMPORARY = re.compile(r"^\..+\.[0-9a-f]{12}\.tmp(\.[^.]*)?$")


def lock_path(out: str | os.PathLike[str]) -> Path:
    """The lock file of the output folder ``out``: ``.NAME.soilstats-lock`` beside it."""
    real = Path(os.path.realpath(out))
    return real.parent / f".{real.name}.soilstats-lock"


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's process: alive
        return True
    except (OSError, OverflowError):
        return False
    return True


def _acquire(lock: Path, out: Path, command: str) -> list[str]:
    """Create ``lock`` exclusively; remove a stale one first (returned as a note)."""
    notes: list[str] = []
    record = {
        "pid": os.getpid(),
        "host": socket.gethostname(),
        "command": command,
        "started": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    }
    for _ in range(2):
        try:
            fd = os.open(lock, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o644)
        except FileExistsError:
            other = _read_lock(lock)
            if _holds(other, lock):
                raise InputError(
                    f"--out {str(out)!r} is being written by another soilstats run (pid "
                    f"{other.get('pid', '?')} on {other.get('host', '?')}, started "
                    f"{other.get('started', '?')}: {other.get('command', '?')}); wait for it "
                    "to end or choose another --out. If no such run exists, remove "
                    f"{str(lock)!r}"
                ) from None
            with contextlib.suppress(FileNotFoundError):
                os.unlink(lock)
            notes.append(
                f"removed the stale lock of a soilstats run that ended without releasing "
                f"--out (pid {other.get('pid', '?')}, {other.get('command', 'unknown command')}"
                f", started {other.get('started', '?')})"
            )
            continue
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            json.dump(record, fh)
        return notes
    raise InputError(f"cannot take the lock {str(lock)!r} of --out {str(out)!r}; try again")


def _read_lock(lock: Path) -> dict:
    try:
        value = json.loads(lock.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        value = {}
    return value if isinstance(value, dict) else {}


def _holds(other: dict, lock: Path) -> bool:
    """Whether the run that wrote the lock record ``other`` may still be running."""
    pid = other.get("pid")
    if not isinstance(pid, int):  # being written this instant, or unreadable: judge by age
        try:
            return time.time() - lock.stat().st_mtime < 60
        except OSError:
            return False
    if other.get("host") != socket.gethostname():
        return True  # another machine's run: cannot tell, so it holds
    return _pid_alive(pid)


def _release(lock: Path) -> None:
    if _read_lock(lock).get("pid") == os.getpid():
        with contextlib.suppress(FileNotFoundError):
            os.unlink(lock)


def _leftovers(real: Path, *, beside: bool) -> list[str]:
    """Remove what killed runs left (their stages, a set moved aside, stray temporaries),
    restoring a set moved aside when DIR itself is missing; one note for each."""
    notes = []
    parent = real.parent
    pattern = f".{real.name}.soilstats-"
    found = sorted(parent.glob(glob_escape(pattern) + "*")) if beside else []
    old = [p for p in found if p.name.startswith(pattern + "old-") and p.is_dir()]
    if old and not os.path.lexists(real):
        os.rename(old[-1], real)  # interrupted between the two renames: the old set is whole
        notes.append(f"restored {str(real)!r} from {old[-1].name}, set aside by an interrupted run")
        old = old[:-1]
    for p in found:
        if p.name.startswith((pattern + "stage-", pattern + "old-")) and p.exists():
            shutil.rmtree(p, ignore_errors=True)
            notes.append(f"removed {p.name}, the unfinished output set of an interrupted run")
    if real.is_dir():
        for p in sorted(real.rglob(".*")):
            if _TEMPORARY.match(p.name) and (p.is_file() or p.is_symlink()):
                p.unlink()
                notes.append(f"removed {str(p)!r}, a temporary file an interrupted run left")
    return notes


def glob_escape(text: str) -> str:
    """``text`` with the glob metacharacters escaped (a folder named ``a[1]``)."""
    return re.sub(r"([*?\[])", r"[\1]", text)


def _snapshot(real: Path, stage: Path) -> dict[str, tuple[int, int]]:
    """Fill ``stage`` with hard links of everything in ``real`` (copies where a hard link is
    refused), never of the stage itself or the lock (inside DIR when DIR's parent cannot be
    written); return relpath -> (dev, ino) of each entry."""
    snap: dict[str, tuple[int, int]] = {}
    for root, dirs, names in os.walk(real):
        if Path(root) == real:
            dirs[:] = [d for d in dirs if (real / d) != stage]
        rel_root = Path(root).relative_to(real)
        for d in list(dirs):
            src, dst = Path(root) / d, stage / rel_root / d
            if src.is_symlink():
                os.symlink(os.readlink(src), dst)
                dirs.remove(d)
                snap[str(rel_root / d)] = _key(dst)
            else:
                dst.mkdir()
                shutil.copymode(src, dst)
        for n in names:
            if Path(root) == real and n == ".soilstats-lock":
                continue
            _link(Path(root) / n, stage / rel_root / n)
            snap[str(rel_root / n)] = _key(stage / rel_root / n)
    return snap


def _key(path: Path) -> tuple[int, int]:
    st = os.lstat(path)
    return (st.st_dev, st.st_ino)


def _link(src: Path, dst: Path) -> None:
    if src.is_symlink():
        os.symlink(os.readlink(src), dst)
        return
    try:
        os.link(src, dst, follow_symlinks=False)
    except OSError:  # no hard links here (protected_hardlinks, a file system without them)
        shutil.copy2(src, dst, follow_symlinks=False)


def _entries(folder: Path) -> dict[str, tuple[int, int]]:
    """relpath -> (dev, ino) of every file or link under ``folder`` (folders: recursed)."""
    out = {}
    for root, dirs, names in os.walk(folder):
        rel_root = Path(root).relative_to(folder)
        for d in list(dirs):
            if (Path(root) / d).is_symlink():
                out[str(rel_root / d)] = _key(Path(root) / d)
                dirs.remove(d)
        for n in names:
            out[str(rel_root / n)] = _key(Path(root) / n)
    return out


def _exchange(a: Path, b: Path) -> bool:
    """Swap the folders ``a`` and ``b`` atomically (Linux ``renameat2``); False where the
    system cannot."""
    try:
        renameat2 = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError):
        return False
    at_fdcwd, rename_exchange = -100, 2
    if renameat2(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), rename_exchange) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.EINVAL, errno.ENOSYS, errno.EOPNOTSUPP, errno.EPERM):
        return False
    raise OSError(err, os.strerror(err), str(b))


def _commit(real: Path, stage: Path, snap: dict, overwrite: bool, in_place: bool) -> None:
    now = _entries(stage)
    written = sorted(rel for rel, key in now.items() if snap.get(rel) != key)
    removed = sorted(set(snap) - set(now))
    if not written and not removed:
        shutil.rmtree(stage, ignore_errors=True)
        return
    current = _entries(real) if real.is_dir() else {}
    if not overwrite:  # existence checked again now: a file may have appeared since the start
        late = [rel for rel in written if rel in current and rel not in snap]
        if late:
            raise InputError(
                f"{real / late[0]}: appeared in --out while this run was writing; nothing of "
                "the run was written (give --overwrite to replace it)"
            )
    if in_place:
        for rel in written:
            (real / rel).parent.mkdir(parents=True, exist_ok=True)
            os.replace(stage / rel, real / rel)
        for rel in removed:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(real / rel)
        shutil.rmtree(stage, ignore_errors=True)
        return
    # What others put in DIR meanwhile is kept: linked into the set that replaces it.
    for rel, key in current.items():
        if rel in written or rel in removed or now.get(rel) == key:
            continue
        target = stage / rel
        target.parent.mkdir(parents=True, exist_ok=True)
        if os.path.lexists(target):
            os.unlink(target)
        _link(real / rel, target)
    if not real.exists():
        os.rename(stage, real)
    elif _exchange(stage, real):
        shutil.rmtree(stage, ignore_errors=True)  # the old set, now under the stage's name
    else:
        aside = stage.with_name(stage.name.replace("-stage-", "-old-"))
        os.rename(real, aside)
        os.rename(stage, real)  # between the two: the next run restores ``aside``
        shutil.rmtree(aside, ignore_errors=True)


def _working_folder_inside(real: Path) -> bool:
    try:
        cwd = Path(os.path.realpath(os.getcwd()))
    except OSError:
        return False
    return cwd == real or real in cwd.parents


@contextlib.contextmanager
def output_set(
    out: str | os.PathLike[str], *, overwrite: bool = False, command: str | None = None
) -> Iterator[Path]:
    """Run the block with the output folder ``out`` locked and staged (module docstring).

    The command line wraps every run in it; from Python it makes any number of writes one
    set, exactly as a command's::

        with output_set("runs/soil01", overwrite=True):
            campaign.save("runs/soil01/data", overwrite=True)
            write_json("runs/soil01/fit.json", fit.to_dict(), provenance, overwrite=True)

    Every writer of :mod:`soilstats.outputs.files` (and every ``save``/``to_netcdf`` of the
    package, which write through them) is staged, wherever it is called from.
    Every file written under ``out`` inside the block goes to the stage and appears in ``out``
    only when the block ends without an exception, all at once; an exception leaves ``out``
    as it was. Without this block each library writer is atomic per file only (a crash
    between two files leaves the first new beside the second old).

    Parameters
    ----------
    out : str or os.PathLike
        The output folder (created at commit if absent).
    overwrite : bool
        Replace files ``out`` already holds (default: refuse, naming the file).
    command : str, optional
        What the lock records for a second run to name (default: this Python process's
        command line).

    Yields
    ------
    Path
        ``out`` as given: write to it as usual.

    Raises
    ------
    InputError
        Another live run holds ``out`` (exit 2, naming it).
        Or, without ``overwrite``, a file the run wrote appeared in ``out`` meanwhile.
    """
    out = Path(out)
    if command is None:
        command = " ".join(["python", *map(str, sys.argv)]).strip()
    if os.path.islink(out) and not out.exists():
        yield out  # a dangling link: the writers refuse it with their own message
        return
    real = Path(os.path.realpath(out))
    real.parent.mkdir(parents=True, exist_ok=True)
    beside = os.access(real.parent, os.W_OK | os.X_OK)
    if not beside and not real.is_dir():
        yield out  # nowhere to stage: the writers' own checks apply
        return
    lock = lock_path(real) if beside else real / ".soilstats-lock"
    notes = _acquire(lock, out, command)
    try:
        notes += _leftovers(real, beside=beside)
        for note in notes:
            warnings.warn(note, SoilstatsWarning, stacklevel=3)
        in_place = not beside or _working_folder_inside(real)
        home = real.parent if beside else real
        stage = Path(tempfile.mkdtemp(prefix=f".{real.name}.soilstats-stage-", dir=home))
        try:
            mode = real.stat().st_mode if real.is_dir() else 0o777 & ~_umask()
            os.chmod(stage, mode & 0o7777)
            snap = _snapshot(real, stage) if real.is_dir() else {}
            with files.staging(real, stage):
                yield out
            _commit(real, stage, snap, overwrite, in_place)
        except OSError as err:  # named as the user named it, not by the stage's name
            shutil.rmtree(stage, ignore_errors=True)
            if isinstance(err.strerror, str):  # "no space left to write X into 'STAGE'"
                err.strerror = err.strerror.replace(str(stage), str(out))
            for attr in ("filename", "filename2"):
                name = getattr(err, attr, None)
                if isinstance(name, str) and Path(name).is_relative_to(stage):
                    setattr(err, attr, str(out / Path(name).relative_to(stage)))
            raise
        except BaseException:
            shutil.rmtree(stage, ignore_errors=True)
            raise
    finally:
        _release(lock)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
