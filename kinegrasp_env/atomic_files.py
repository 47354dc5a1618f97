"""Writing a file whole or not at all: through a temporary file in the same folder and a
rename (:func:`write_atomic`), with the permissions a plain ``open(path, "w")`` gives
(:func:`file_mode`), so that an interrupted run never leaves half a file a later run reads."""

from __future__ import annotations

import os
import stat
import tempfile
from pathlib import Path


def write_atomic(path: str | Path, text: str | bytes) -> None:
    """Write text (or bytes) through a temporary file in the same folder and a rename.

    The file gets the permissions a plain ``open(path, "w")`` would give it: an existing
    file's mode is kept, a new file gets ``0o666 & ~umask`` (the temporary file's private
    0600 is not passed on).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        os.fchmod(fd, file_mode(path))
        with os.fdopen(fd, "wb" if isinstance(text, bytes) else "w") as handle:
            handle.write(text)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


def current_umask() -> int:
    """The process's umask (read by setting it and putting it back at once)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def file_mode(path: str | Path) -> int:
    """Permission bits for (re)writing ``path``: its current ones if it exists, else the
    mode a new file gets under the umask (``0o666 & ~umask``)."""
    try:
        return stat.S_IMODE(os.stat(path).st_mode)
    except FileNotFoundError:
        return 0o666 & ~current_umask()
