"""Every file the package writes: complete or absent, and never replacing one it must not.

Two ways to write, one for each promise:

* :func:`new_file` — a result (time series, plots and CSV of a report, parameter files of a
  calibration, campaign outputs, recordings' ``metadata.yaml``): written to a hidden temporary
  file in the target's folder, flushed to disk (``fsync``), then published under its name
  **without replacing anything**: a hard link to the name (which fails if the name exists),
  then the temporary name removed. A file system without hard links (some FAT, SMB or FUSE
  mounts) gets an exclusive create of the name, filled from the synced temporary file: that
  never replaces either, but a crash during the copy can leave the name short (the only case
  where a partial file can carry a result's name). An existing name is refused with
  :class:`FileExistsError` naming it.
* :func:`replaced_file` — a file the package updates on purpose (campaign progress and
  manifests, the report folder's files when a report is made again, the user's compile
  times): the same temporary file and ``fsync``, then :func:`os.replace`, atomic on POSIX.

Either way a failed write (a full disk, an interrupt) removes the temporary file, leaves the
target as it was, and raises an :class:`OSError` whose ``filename`` is the target. Temporary
names are random and created exclusively (``O_EXCL``, no symbolic link followed), so a
folder others can write cannot redirect them.
"""
from __future__ import annotations

import contextlib
import errno
import os
import secrets
import shutil
from pathlib import Path
from typing import IO, Iterator

__all__ = ["file_part", "new_file", "one_line", "replaced_file", "write_new",
           "write_replacing"]

#: Errors of :func:`os.link` that mean "this file system has no hard links".
_NO_LINKS = {errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP, errno.ENOSYS, errno.EMLINK,
             errno.EXDEV}


class _Checked:
    """A file object whose write errors name the target file."""

    def __init__(self, fh: IO, target: Path):
        self._fh, self._target = fh, target

    def write(self, data):
        try:
            return self._fh.write(data)
        except OSError as exc:
            raise _naming(exc, self._target) from None

    def __getattr__(self, name):
        return getattr(self._fh, name)

    def __iter__(self):
        return iter(self._fh)


#: Flags of a file created here: new, never through a symbolic link.
_EXCLUSIVE = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0) \
    | getattr(os, "O_BINARY", 0)


def _exclusive(path, flags: int) -> int:
    """``open``'s opener: create ``path`` exclusively (mode 0666 less the umask)."""
    return os.open(path, _EXCLUSIVE, 0o666)


def _temporary(target: Path, mode: str, open_kw: dict) -> tuple[IO, Path]:
    """A new hidden file beside ``target``, open for writing."""
    for _ in range(100):
        tmp = target.with_name(f".{target.name}.{secrets.token_hex(4)}.tmp")
        try:
            return open(tmp, mode, opener=_exclusive, **open_kw), tmp  # noqa: SIM115
        except FileExistsError:
            continue
        except OSError as exc:
            raise _naming(exc, target) from None
    raise _naming(FileExistsError(errno.EEXIST, "no free temporary name"), target)


def _sync(fh: IO) -> None:
    """Flush ``fh`` to the disk."""
    fh.flush()
    fileno = getattr(fh, "fileno", None)
    if fileno is not None:
        os.fsync(fileno())


def _sync_folder(folder: Path) -> None:
    """Make a rename or link in ``folder`` durable (where folders can be opened)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _publish_new(tmp: Path, target: Path) -> None:
    """Give the synced ``tmp`` the name ``target`` unless that name exists."""
    try:
        os.link(tmp, target)
    except FileExistsError:
        raise FileExistsError(errno.EEXIST, "exists: choose a new name (nothing is "
                              "overwritten)", str(target)) from None
    except OSError as exc:
        if exc.errno not in _NO_LINKS:
            raise _naming(exc, target) from None
        _copy_exclusive(tmp, target)
    tmp.unlink()


def _copy_exclusive(tmp: Path, target: Path) -> None:
    """The fallback of a file system without hard links: create ``target`` exclusively and
    fill it from ``tmp``; on failure remove what was created."""
    try:
        fd = _exclusive(target, 0)
    except FileExistsError:
        raise FileExistsError(errno.EEXIST, "exists: choose a new name (nothing is "
                              "overwritten)", str(target)) from None
    except OSError as exc:
        raise _naming(exc, target) from None
    try:
        with os.fdopen(fd, "wb") as out, open(tmp, "rb") as src:
            shutil.copyfileobj(src, out)
            _sync(out)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            target.unlink()
        if isinstance(exc, OSError):
            raise _naming(exc, target) from None
        raise


@contextlib.contextmanager
def _written(path, mode: str, replace: bool, open_kw: dict) -> Iterator[IO]:
    if mode not in ("w", "wb"):
        raise ValueError(f"mode must be 'w' or 'wb', got {mode!r}")
    target = Path(path)
    fh, tmp = _temporary(target, mode, open_kw)
    try:
        yield _Checked(fh, target)
        _sync(fh)
        fh.close()
        if replace:
            os.replace(tmp, target)
        else:
            _publish_new(tmp, target)
        _sync_folder(target.parent)
    except BaseException as exc:
        with contextlib.suppress(OSError, ValueError):
            fh.close()
        with contextlib.suppress(OSError):
            tmp.unlink()
        if isinstance(exc, OSError) and not exc.filename:
            raise _naming(exc, target) from None
        raise


def new_file(path, mode: str = "w", **open_kw) -> contextlib.AbstractContextManager[IO]:
    """Open a new file ``path`` for writing: it appears complete or not at all, and never
    replaces a file of that name.

    Parameters
    ----------
    path : str or path-like
        The file to create; its folder must exist.
    mode : str, optional
        ``"w"`` (text) or ``"wb"`` (binary).
    **open_kw
        Passed to :func:`open` (``encoding``, ``newline``).

    Returns
    -------
    context manager yielding a file object

    Raises
    ------
    FileExistsError
        ``path`` exists (when the content is complete; nothing is written).
    OSError
        Opening, writing, syncing or publishing failed (``filename`` is ``path``); nothing of
        the new content is left behind.
    """
    return _written(path, mode, False, open_kw)


def replaced_file(path, mode: str = "w", **open_kw) -> contextlib.AbstractContextManager[IO]:
    """Open ``path`` for writing a new version of it, replaced atomically when complete.

    For files the package updates on purpose; results use :func:`new_file`.

    Parameters
    ----------
    path : str or path-like
    mode : str, optional
        ``"w"`` (text) or ``"wb"`` (binary).
    **open_kw
        Passed to :func:`open`.

    Returns
    -------
    context manager yielding a file object

    Raises
    ------
    OSError
        Writing failed (``filename`` is ``path``); the old version is left as it was.
    """
    return _written(path, mode, True, open_kw)


def write_new(path, data: bytes | str, encoding: str = "utf-8") -> Path:
    """Write ``data`` to the new file ``path`` (:func:`new_file`); the path written."""
    binary = isinstance(data, (bytes, bytearray, memoryview))
    with new_file(path, "wb" if binary else "w",
                  **({} if binary else {"encoding": encoding})) as fh:
        fh.write(data)
    return Path(path)


def write_replacing(path, data: bytes | str, encoding: str = "utf-8") -> Path:
    """Write ``data`` as the new version of ``path`` (:func:`replaced_file`); the path."""
    binary = isinstance(data, (bytes, bytearray, memoryview))
    with replaced_file(path, "wb" if binary else "w",
                       **({} if binary else {"encoding": encoding})) as fh:
        fh.write(data)
    return Path(path)


def one_line(text: str) -> str:
    """``text`` with its control and format characters written as escapes (``\\n``,
    ``\\x1b``, ``\\u202e``): one line that no reader takes for a line break or a command.

    For text that ends up inside other text (a comment of a written file, a terminal line).
    """
    import unicodedata

    return "".join(c if not (unicodedata.category(c)[0] == "C"
                             or unicodedata.category(c) in ("Zl", "Zp"))
                   else c.encode("unicode_escape").decode("ascii") for c in text)


def file_part(name: str) -> str:
    """A user-given name as part of a file name: letters, digits, ``.``, ``-`` and ``_`` kept,
    anything else (a path separator among them) replaced by ``_``, and then a digest of the
    name added, so that two names never give one file.

    Parameters
    ----------
    name : str

    Returns
    -------
    str
    """
    import hashlib
    import re

    safe = re.sub(r"[^A-Za-z0-9._-]", "_", name)[:80]
    if safe == name:
        return name
    return f"{safe}-{hashlib.sha256(name.encode()).hexdigest()[:8]}"


def _naming(exc: OSError, target: Path) -> OSError:
    """``exc`` naming ``target`` (OSError picks the subclass of the errno)."""
    if exc.errno is None:
        return OSError(f"{target}: {exc}")
    return OSError(exc.errno, exc.strerror, str(target))
