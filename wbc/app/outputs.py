"""The files ``wbc run`` writes (``--plot``, ``--html``): checked before the run starts, written
atomically (a temporary file in the target folder, renamed over the target once complete), so
a failed or interrupted write leaves no partial file."""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import BinaryIO

from ..core.errors import WbcError

#: what ``--html`` (:func:`wbc.app.view.write_html`) writes, by suffix
HTML_FORMATS = {".html": "HTML page", ".htm": "HTML page"}


def write_atomically(path: str | Path, write: Callable[[BinaryIO], object]) -> Path:
    """Create the folder of ``path`` if missing, call ``write`` with a binary stream on a
    temporary file next to ``path``, then rename it to ``path`` (:func:`os.replace`). On any
    exception (Ctrl-C included) the temporary file is removed and ``path`` is untouched.

    Returns:
        ``path``, as a :class:`~pathlib.Path`.

    Raises:
        OSError: the folder, the temporary file or the rename failed (e.g. no permission, the
            disk is full); and whatever ``write`` raises, unchanged.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    descriptor, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(descriptor, "wb") as stream:
            write(stream)
        os.chmod(temporary, 0o666 & ~_umask())
        os.replace(temporary, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(temporary)
        raise
    return path


def _umask() -> int:
    """The process's umask (read by setting it and putting it back)."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


class OutputError(WbcError, ValueError):
    """An output path that cannot be written, with what to give instead."""


def check_output(path_text: str, formats: Mapping[str, str]) -> Path:
    """``path_text`` as the path of a file that can be written in one of ``formats``
    (suffix -> description, e.g. ``{".png": "PNG image"}``): a file name with one of those
    suffixes, not a folder, in a folder that exists and is writable or can be created.
    Nothing is created.

    Returns:
        The path, as a :class:`~pathlib.Path`.

    Raises:
        OutputError: saying what is wrong and what to give: an empty name, a folder, a suffix
            not in ``formats``, a folder that cannot be created or written in.
    """
    if not path_text.strip():
        raise OutputError("needs a file name")
    path = Path(path_text)
    if path.is_dir() or path_text.endswith(("/", os.sep)):
        example = path / f"run{next(iter(formats))}"
        raise OutputError(f"{path_text} is a folder; give a file name in it, e.g. {example}")
    if path.suffix.lower() not in formats:
        first, *others = formats
        known = first + (f" (or {', '.join(others[:4])}{', ...' if len(others) > 4 else ''})" if others else "")
        got = f"suffix {path.suffix!r}" if path.suffix else "no suffix"
        raise OutputError(f"{path_text} has {got}; give a name ending in {known}")
    folder = path.parent
    existing = next(parent for parent in (folder, *folder.parents) if parent.exists())
    if not existing.is_dir():
        raise OutputError(f"cannot create the folder {folder}: {existing} is not a folder")
    try:
        with tempfile.TemporaryFile(dir=existing):
            pass
    except OSError as exc:
        reason = exc.strerror or str(exc)
        raise OutputError(f"cannot write in {existing}: {reason}; give a path in a writable folder") from None
    return path
