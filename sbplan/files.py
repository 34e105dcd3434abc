"""Writing files safely: atomic single files, folders written as one unit, and the checks every
output passes before a command does its work.

- :func:`write_atomic` writes a temporary file in the same folder and renames it over the target:
  a failed or killed run never leaves a half-written file and never destroys a good one.
- :func:`write_file_set` writes several files that belong together (a nav2 ``map.yaml`` and its
  ``map.pgm``, the demo's output folder) into a temporary folder and swaps it with the old one in
  one step (Linux ``renameat2(RENAME_EXCHANGE)``): a reader sees the old set or the new one, never
  a mix, however many writers run at once and wherever one is killed.
- :func:`write_folder` does the same for a set written by a function into a temporary folder
  (rendered scenes, a video and its truth).
- :func:`check_outputs` refuses, before any work, outputs that are not regular files (devices,
  FIFOs, symbolic links, folders), outputs that are one of the command's inputs, and one file named
  for two outputs.
- Temporary files and folders are named ``.NAME.HOST-PID-RANDOM.tmp``; those whose process is gone
  (killed runs) are removed by the next write into the same folder.

Every failure is an :class:`~sbplan.errors.OutputError` with a one-line message naming the path.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import hashlib
import json
import os
import re
import secrets
import shutil
import socket
import stat
import tempfile
import time
from pathlib import Path
from typing import IO, Any, Callable, Iterable, Mapping

from .errors import OutputError

#: Temporary files of another host, or in the old unnamed form, count as stale after this long.
STALE_SECONDS = 3600.0

_HOST = hashlib.sha1(socket.gethostname().encode("utf-8", "replace")).hexdigest()[:6]
_TMP = re.compile(r"^\.(?P<name>.+)\.(?P<host>[0-9a-f]{6})-(?P<pid>\d+)-[A-Za-z0-9_]+\.tmp$")
# Temporary files written before they carried their owner (mkstemp's 8 random characters)
_OLD_TMP = re.compile(r"^\.(?P<name>.+)\.[A-Za-z0-9_]{8}\.tmp$")


def _fail(path: Any, exc: OSError, doing: str = "cannot write") -> OutputError:
    reason = exc.strerror or str(exc)
    return OutputError(f"{path}: {doing} ({reason})")


def _tmp_prefix(name: str) -> str:
    # leave room for the owner tag and mkstemp's suffix within a 255-byte file name
    return f".{name[:180]}.{_HOST}-{os.getpid()}-"


def _check_target(p: Path, *, folder: bool = False) -> None:
    """Refuse a target that exists and is not what sbplan may replace."""
    try:
        st = os.lstat(p)
    except FileNotFoundError:
        return
    except NotADirectoryError:
        raise OutputError(f"{p}: a part of the path is a file, not a folder") from None
    except OSError as exc:
        raise _fail(p, exc, "cannot be checked") from None
    if stat.S_ISLNK(st.st_mode):
        raise OutputError(f"{p}: is a symbolic link; sbplan replaces outputs and would replace the link: "
                          f"give the path of a regular {'folder' if folder else 'file'}")
    if folder:
        if stat.S_ISREG(st.st_mode):
            raise OutputError(f"{p}: is a file, not a folder")
        if not stat.S_ISDIR(st.st_mode):
            raise OutputError(f"{p}: is not a folder (a device, FIFO or socket)")
        return
    if stat.S_ISDIR(st.st_mode):
        raise OutputError(f"{p}: is a folder; give a file name")
    if not stat.S_ISREG(st.st_mode):
        raise OutputError(f"{p}: is not a regular file (a device, FIFO or socket); sbplan writes only "
                          "regular files")


def _make_folder(folder: Path) -> None:
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise _fail(folder, exc, "cannot make the folder") from None
    if not folder.is_dir():
        raise OutputError(f"{folder}: is a file, not a folder")


def write_atomic(path: str | os.PathLike, write: Callable[[Any], None] | bytes | str, *, binary: bool = True) -> Path:
    """Write a file atomically. ``write`` is the content, or a function given the open file.

    Raises
    ------
    OutputError
        The target is a folder, a device, a FIFO or a symbolic link, or the file cannot be written
        (no such folder, no permission, disk full). Errors raised by a ``write`` function other
        than OSError pass through unchanged; either way the old file stays as it was.
    """
    p = Path(path)
    folder = p.parent if str(p.parent) else Path(".")
    _check_target(p)
    _make_folder(folder)
    try:
        fd, tmp = tempfile.mkstemp(prefix=_tmp_prefix(p.name), suffix=".tmp", dir=folder)
    except OSError as exc:
        raise _fail(p, exc) from None
    try:
        # mkstemp makes the file private (0600); a result file should be as readable as any other
        # (a replaced file keeps its mode)
        os.chmod(tmp, p.stat().st_mode & 0o7777 if p.exists() else 0o644)
        fh: IO[Any] = (os.fdopen(fd, "w", encoding="utf-8") if callable(write) and not binary
                       else os.fdopen(fd, "wb"))
        with fh:
            if callable(write):
                write(fh)
            else:
                fh.write(write.encode("utf-8") if isinstance(write, str) else write)
            fh.flush()
            os.fsync(fh.fileno())
        _check_target(p)  # made a special file or a link while we wrote: still not ours to replace
        os.replace(tmp, p)
    except BaseException as exc:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        if isinstance(exc, OSError) and not isinstance(exc, OutputError):
            raise _fail(p, exc) from None
        raise
    clean_stale_temporaries(folder)
    return p


def write_json(path: str | os.PathLike, obj: Any) -> Path:
    """Write ``obj`` as indented JSON, atomically."""
    text = json.dumps(obj, indent=2, default=json_default) + "\n"
    return write_atomic(path, text)


def json_default(obj: Any) -> Any:
    """``json.dumps(default=...)`` for numpy values, arrays, paths and tuples."""
    import numpy as np  # imported when used: writing files needs no numpy

    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, tuple):
        return list(obj)
    raise TypeError(f"not JSON serializable: {type(obj).__name__}")


# -- folders written as one unit ----------------------------------------------------------------

_RENAME_EXCHANGE = 2
_AT_FDCWD = -100


def _exchange(a: Path, b: Path) -> bool:
    """Swap two paths in one step (Linux renameat2 RENAME_EXCHANGE). False where the system or
    the file system cannot."""
    try:
        fn = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError):
        return False
    fn.restype = ctypes.c_int
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    if fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.ENOSYS, errno.EINVAL, errno.EOPNOTSUPP):
        return False
    raise OSError(err, os.strerror(err), str(b))


def _fsync_dir(folder: Path) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def check_set_folder(folder: str | os.PathLike, names: Iterable[str] | Callable[[str], bool], *,
                     what: str = "output folder") -> Path:
    """Refuse a folder :func:`write_file_set` must not replace: a link, a file, the working folder
    or one above it, or a folder holding anything but ``names`` (top-level names the set may
    hold, or a function saying whether a name is one) and sbplan's temporaries."""
    folder = Path(folder)
    _check_target(folder, folder=True)
    if folder.exists():
        here = Path.cwd().resolve()
        full = folder.resolve()
        if full == here or full in here.parents:
            raise OutputError(f"{what} {folder}: is the working folder or holds it; sbplan replaces the whole "
                              "folder: give a folder of its own")
        allowed = names if callable(names) else set(names).__contains__
        try:
            entries = sorted(os.listdir(folder))
        except OSError as exc:
            raise _fail(folder, exc, "cannot be read") from None
        foreign = [e for e in entries if not allowed(e) and not (_TMP.match(e) or _OLD_TMP.match(e))]
        if foreign:
            more = f" (and {len(foreign) - 1} more)" if len(foreign) > 1 else ""
            raise OutputError(f"{what} {folder}: holds {foreign[0]!r}{more}, which sbplan did not write there; "
                              "sbplan replaces the whole folder: give a new or empty folder")
    return folder


def write_file_set(folder: str | os.PathLike, files: Mapping[str, bytes | str], *,
                   names: Iterable[str] | None = None) -> Path:
    """Write files that belong together into ``folder`` as one unit.

    The files are written into a temporary folder beside ``folder``, which then takes the old
    folder's place in one step: a reader (nav2's map_server, ``sbplan plan``, another process)
    sees the complete old set or the complete new one, never a mix, however many writers run at
    once and wherever one is killed. The old folder is removed, so ``folder`` may hold only what
    such a set holds (``names``); anything else is refused rather than deleted.

    Parameters
    ----------
    folder : path
    files : mapping of relative path (``/``-separated, subfolders allowed) -> content
        Text is written as UTF-8.
    names : iterable of str, optional
        Every top-level name a set of this kind may hold (default: those of ``files``).

    Raises
    ------
    OutputError
        The folder is a link, a file, the working folder, holds files that are not the set's,
        or cannot be written.

    Notes
    -----
    Where the swap in one step is not available (not Linux, or a file system without
    RENAME_EXCHANGE) the old folder is moved aside and the new one moved in: a reader may then
    find no folder for that instant, but still never a mix.
    """
    tops = {rel.split("/", 1)[0] for rel in files}

    def fill(tmp: Path) -> None:
        for rel, content in files.items():
            target = tmp.joinpath(*rel.split("/"))
            target.parent.mkdir(parents=True, exist_ok=True)
            data = content.encode("utf-8") if isinstance(content, str) else bytes(content)
            with open(target, "wb") as fh:
                fh.write(data)
            os.chmod(target, 0o644)

    write_folder(folder, fill, names=tops | set(names or ()))
    return Path(folder)


def write_folder(folder: str | os.PathLike, fill: Callable[[Path], Any], *,
                 names: Iterable[str] | Callable[[str], bool]) -> Any:
    """Write a folder as one unit, as :func:`write_file_set` does, with ``fill`` writing its files.

    ``fill`` is given an empty temporary folder beside ``folder`` and writes the set into it (files
    too large to hold in memory at once, a video that OpenCV writes to a path); every file in it
    is then flushed to disk and the folder takes ``folder``'s place in one step. Killed or failing
    in ``fill``, the old folder stays as it was.

    Parameters
    ----------
    names : iterable of str, or function of str -> bool
        The top-level names a folder of this kind may hold (see :func:`check_set_folder`).

    Returns
    -------
    What ``fill`` returns.
    """
    folder = Path(folder)
    check_set_folder(folder, names)
    parent = folder.parent if str(folder.parent) else Path(".")
    _make_folder(parent)
    try:
        tmp = Path(tempfile.mkdtemp(prefix=_tmp_prefix(folder.name), suffix=".tmp", dir=parent))
    except OSError as exc:
        raise _fail(folder, exc) from None
    try:
        os.chmod(tmp, 0o755)
        result = fill(tmp)
        for sub, _, names_in in os.walk(tmp):
            for name in names_in:
                fd = os.open(os.path.join(sub, name), os.O_RDONLY)
                try:
                    os.fsync(fd)
                finally:
                    os.close(fd)
            _fsync_dir(Path(sub))
        _swap_in(tmp, folder)
    except BaseException as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        if isinstance(exc, OSError) and not isinstance(exc, OutputError):
            raise _fail(folder, exc) from None
        raise
    _fsync_dir(parent)
    clean_stale_temporaries(parent)
    return result


def _swap_in(tmp: Path, folder: Path) -> None:
    """Put the complete folder ``tmp`` at ``folder``; the old one (if any) is removed."""
    for _ in range(50):  # other writers swap too: a step another one got in between is tried again
        try:
            os.rename(tmp, folder)  # no folder yet (or an empty one): a plain rename is one step
            return
        except OSError as exc:
            if exc.errno not in (errno.EEXIST, errno.ENOTEMPTY):
                raise
        _check_target(folder, folder=True)
        try:
            swapped = _exchange(tmp, folder)
        except FileNotFoundError:
            continue  # another writer moved the folder aside this instant
        if swapped:
            shutil.rmtree(tmp, ignore_errors=True)  # tmp holds the old set now
            return
        aside = folder.parent / f"{_tmp_prefix(folder.name)}{secrets.token_hex(4)}.tmp"
        try:
            os.rename(folder, aside)
        except FileNotFoundError:
            continue
        try:
            os.rename(tmp, folder)
        except OSError as exc:
            if exc.errno not in (errno.EEXIST, errno.ENOTEMPTY):
                raise
            continue
        finally:
            shutil.rmtree(aside, ignore_errors=True)
        return
    raise OutputError(f"{folder}: other processes keep replacing it; could not put the new files in place")


# -- stale temporaries --------------------------------------------------------------------------

def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True  # another user's process
    return True


def clean_stale_temporaries(folder: str | os.PathLike) -> list[str]:
    """Remove the temporary files and folders that killed sbplan runs left in ``folder``.

    A temporary of this host whose process is gone is stale at once; one of another host (a
    shared folder) or in the form older versions wrote, after :data:`STALE_SECONDS`. Returns the
    names removed.
    """
    removed: list[str] = []
    now = time.time()
    try:
        entries = list(os.scandir(os.fspath(folder)))
    except OSError:
        return removed
    for entry in entries:
        name = entry.name
        if not (name.startswith(".") and name.endswith(".tmp")):
            continue
        m = _TMP.match(name)
        if m and m["host"] == _HOST:
            stale = not _alive(int(m["pid"]))
        elif m or _OLD_TMP.match(name):
            try:
                stale = now - entry.stat(follow_symlinks=False).st_mtime > STALE_SECONDS
            except OSError:
                continue
        else:
            continue
        if not stale:
            continue
        try:
            if entry.is_dir(follow_symlinks=False):
                shutil.rmtree(entry.path)
            else:
                os.unlink(entry.path)
            removed.append(name)
        except OSError:
            pass  # gone already, or not ours to remove
    return removed


# -- checks before the work ----------------------------------------------------------------------

def _same(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return os.path.abspath(a) == os.path.abspath(b)


def check_outputs(outputs: Mapping[str, Any], inputs: Mapping[str, Any] | None = None, *,
                  folders: Mapping[str, Iterable[str]] | None = None, images: Iterable[str] = ()) -> None:
    """Refuse, before any work, outputs a command must not write.

    Parameters
    ----------
    outputs : mapping of option -> path (None: not given)
        Single-file outputs.
    inputs : mapping of option -> path (None: not given)
        The command's input files; no output may be one of them.
    folders : mapping of option -> names
        Outputs that are folders written by :func:`write_file_set`, with the top-level names such
        a folder may hold; ``option`` is also a key of ``outputs``.
    images : iterable of option
        Outputs that are images: their file ending must name a format OpenCV can write.

    Raises
    ------
    OutputError
        An output is a folder, a device, a FIFO or a symbolic link; is one of the inputs (or holds
        one, for a folder); is named twice; or has an image ending no encoder writes.
    """
    given_in = {k: Path(v) for k, v in (inputs or {}).items() if v is not None}
    given_out = {k: Path(v) for k, v in outputs.items() if v is not None}
    folders = dict(folders or {})
    images = set(images)
    seen: dict[str, str] = {}
    for opt, p in given_out.items():
        if opt in folders:
            for iopt, ip in given_in.items():
                if os.path.realpath(ip).startswith(os.path.realpath(p) + os.sep):
                    raise OutputError(f"{opt} {p}: holds the input {ip} ({iopt}); sbplan replaces the whole "
                                      "folder: give another folder")
            check_set_folder(p, folders[opt], what=opt)
        else:
            _check_target(p)
            for iopt, ip in given_in.items():
                if _same(p, ip):
                    raise OutputError(f"{opt} {p}: is also the input {iopt}; writing it would destroy the input: "
                                      "give another file name")
            if opt in images:
                check_image_ending(p, what=opt)
        key = os.path.realpath(p)
        if key in seen:
            raise OutputError(f"{opt} {p}: is also the output of {seen[key]}; give each output its own name")
        seen[key] = opt
    for opt, p in given_out.items():
        if opt in folders:
            continue
        for fopt, fp in given_out.items():
            if fopt in folders and os.path.realpath(p).startswith(os.path.realpath(fp) + os.sep):
                raise OutputError(f"{opt} {p}: lies inside the folder of {fopt}, which sbplan replaces as a whole")


def check_image_ending(path: str | os.PathLike, *, what: str = "image") -> None:
    """Refuse an image file name whose ending names no format OpenCV can write."""
    import cv2

    p = Path(path)
    ext = p.suffix.lower()
    ok = bool(ext)
    if ok:
        try:
            ok = bool(cv2.haveImageWriter(f"x{ext}"))
        except cv2.error:
            ok = False
    if not ok:
        raise OutputError(f"{what} {p}: cannot write images ending in {ext or '(no ending)'!r}; "
                          "use .png, .pgm, .jpg, .bmp or .tif")
