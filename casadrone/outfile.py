"""Writing a file the user names with ``--out``, as ``run`` writes its run directory: nothing the
user owns is replaced unless asked (``force``), nothing inside a run directory is ever replaced
(its files are the run's state: a damaged ``checkpoint.pkl`` or ``inputs/airframe.yaml`` damages
the run), and a reader never sees half a file (a temporary file in the same folder, then a link
or rename into place).
"""

from __future__ import annotations

import errno
import os
from pathlib import Path

from casadrone.config.io import DATA_DIR

#: The two files every run directory holds (:mod:`casadrone.rundir.store`).
_RUN_MARKERS = ("manifest.json", "config.yaml")


class OutputRefused(ValueError):
    """``--out`` names a file that must not be written (the message says why and what to do)."""


def shown_path(path: str | Path) -> str:
    """How exported files and reports name a file: never a machine's absolute path (the files
    are shared), but ``shipped configs/…`` for the package's own data, the path relative to the
    working folder for a file below it, else the file's name."""
    full = Path(os.path.abspath(path))
    for base, prefix in ((DATA_DIR, "shipped "), (Path.cwd(), "")):
        try:
            return prefix + full.resolve().relative_to(base.resolve()).as_posix()
        except (ValueError, OSError):
            continue
    return full.name


def run_dir_holding(path: Path) -> Path | None:
    """The run directory ``path`` lies in (any folder above it holding a run's manifest and
    config), or None."""
    here = Path(os.path.abspath(path))
    for folder in here.parents:
        if all((folder / name).is_file() for name in _RUN_MARKERS):
            return folder
    return None


def file_above(path: Path) -> Path | None:
    """The first existing ancestor of ``path`` that is not a folder, or None."""
    for folder in reversed(Path(os.path.abspath(path)).parents):
        if folder.exists() and not folder.is_dir():
            return folder
    return None


def check_out(path: str | Path, force: bool = False) -> Path:
    """``path`` when it may be written; else :class:`OutputRefused` saying why."""
    path = Path(path)
    run_dir = run_dir_holding(path)
    if run_dir is not None:
        raise OutputRefused(f"{path}: inside the run directory {run_dir}, whose files are the "
                            "run's own; write the export somewhere else (--force does not "
                            "apply here)")
    blocker = file_above(path)
    if blocker is not None:
        raise OutputRefused(f"{path}: {blocker} is a file, not a folder; choose another --out")
    if path.is_dir():
        raise OutputRefused(f"{path}: is a folder; name a file, e.g. {path / 'export.txt'}")
    if (path.exists() or path.is_symlink()) and not force:
        raise OutputRefused(f"{path}: exists and was left untouched; choose another --out or "
                            "pass --force to replace it")
    return path


def write_out(path: str | Path, text: str | bytes, force: bool = False) -> Path:
    """Write ``text`` (UTF-8; bytes as they are) to ``path`` after :func:`check_out`; atomically,
    and without replacing a file that appeared meanwhile unless ``force``. A failed write (a
    full disk) raises OSError naming ``path`` and leaves no temporary file."""
    path = check_out(path, force)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "wb") as fh:
            fh.write(text.encode("utf-8") if isinstance(text, str) else text)
            fh.flush()
            os.fsync(fh.fileno())
        if force:
            os.replace(tmp, path)
        else:
            _link_new(tmp, path)
    except OSError as exc:
        why = exc.strerror or str(exc)
        if exc.errno in (errno.ENOSPC, errno.EDQUOT):
            why += "; nothing was written: free some space and export again"
        raise OSError(exc.errno, why, str(path)) from None
    finally:
        tmp.unlink(missing_ok=True)
    return path


def _link_new(tmp: Path, path: Path) -> None:
    """Put ``tmp`` at ``path`` only if nothing is there (a hard link fails on an existing
    name; where the file system has no hard links, check and rename)."""
    try:
        os.link(tmp, path)
    except FileExistsError:
        raise OutputRefused(f"{path}: appeared while writing and was left untouched; pass "
                            "--force to replace it") from None
    except OSError as exc:
        if exc.errno not in (errno.EPERM, errno.EXDEV, errno.ENOTSUP, errno.EOPNOTSUPP,
                             errno.EMLINK):
            raise
        if path.exists() or path.is_symlink():
            raise OutputRefused(f"{path}: exists and was left untouched; pass --force to "
                                "replace it") from None
        os.replace(tmp, path)
