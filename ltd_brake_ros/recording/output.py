"""Checked writes: an output file appears complete, or not at all.

Every file the package writes beside a recording or into a report (``metadata.yaml``, plots,
CSV, parameter files) goes through :func:`checked_output`: the data goes to a hidden file
beside the target, which replaces the target only once every write and the close have
succeeded. A full disk or any other failure leaves no half-written file that looks like a
result, and the error names the file that could not be written.
"""
from __future__ import annotations

import contextlib
import os
from pathlib import Path
from typing import IO, Iterator

__all__ = ["checked_output"]


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


@contextlib.contextmanager
def checked_output(path, mode: str = "w", **open_kw) -> Iterator[IO]:
    """Open ``path`` for writing so that it appears complete or not at all.

    Parameters
    ----------
    path : str or path-like
        The file to write (replaced if it exists).
    mode : str, optional
        ``"w"`` (text) or ``"wb"`` (binary).
    **open_kw
        Passed to :func:`open` (``encoding``, ``newline``).

    Yields
    ------
    file object

    Raises
    ------
    OSError
        Opening, writing, closing or renaming failed (``filename`` is ``path``); nothing of the
        new content is left behind.
    """
    if mode not in ("w", "wb"):
        raise ValueError(f"mode must be 'w' or 'wb', got {mode!r}")
    target = Path(path)
    tmp = target.with_name(f".{target.name}.{os.getpid()}.tmp")
    try:
        fh = open(tmp, mode, **open_kw)  # noqa: SIM115 - closed below
    except OSError as exc:
        raise _naming(exc, target) from None
    try:
        yield _Checked(fh, target)
        fh.close()
        os.replace(tmp, target)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            fh.close()
        with contextlib.suppress(OSError):
            tmp.unlink()
        if isinstance(exc, OSError) and not exc.filename:
            raise _naming(exc, target) from None
        raise


def _naming(exc: OSError, target: Path) -> OSError:
    """``exc`` naming ``target`` (OSError picks the subclass of the errno)."""
    if exc.errno is None:
        return OSError(f"{target}: {exc}")
    return OSError(exc.errno, exc.strerror, str(target))
