"""Output files written safely: to a temporary name in the destination's folder, renamed when complete.

A reader never sees a half-written file and a failed or interrupted command leaves the previous file
untouched (`os.replace` is atomic on one file system). `refuse_inputs` stops a command from writing onto
one of its own inputs. Errors are `InputFileError` naming the option and the path.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path

from pmsm_hil.hil.errors import InputFileError


@contextlib.contextmanager
def atomic_path(dest: Path, *, option: str) -> Iterator[Path]:
    """Yield a fresh temporary path beside `dest` (same suffix, so writers that pick the format by the
    extension still work; the file does not exist yet); on a clean exit the file written there replaces
    `dest` (a block that wrote nothing leaves `dest` as it was), on an exception it is removed.

    `option` names the output in errors ("--json", "-o", "output file")."""
    dest = Path(dest)
    folder = dest.parent
    if dest.is_dir():
        raise InputFileError(f"{option} {dest}: is a directory")
    try:
        fd, name = tempfile.mkstemp(prefix=f".{dest.stem}.", suffix=f".tmp{dest.suffix}", dir=folder)
    except FileNotFoundError:
        raise InputFileError(f"{option} {dest}: folder {folder} does not exist") from None
    except OSError as exc:
        raise InputFileError(f"{option} {dest}: cannot write in {folder} ({exc.strerror})") from None
    os.close(fd)
    tmp = Path(name)
    tmp.unlink()  # the writer creates it (with the usual permissions; mkstemp's would be 0600)
    try:
        yield tmp
        if tmp.exists():
            os.replace(tmp, dest)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise InputFileError(f"{option} {dest}: {exc.strerror or exc}") from None
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_text_atomic(dest: Path, text: str, *, option: str) -> None:
    """Write `text` (UTF-8) to `dest` through a temporary file (see `atomic_path`)."""
    with atomic_path(dest, option=option) as tmp:
        tmp.write_text(text, encoding="utf-8")


def same_file(a: Path, b: Path) -> bool:
    """True if `a` and `b` name the same file (symbolic links, `..` and hard links resolved)."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return Path(a).resolve() == Path(b).resolve()


def refuse_inputs(dest: Path, inputs: Iterable[Path], *, option: str) -> None:
    """InputFileError if `dest` is one of `inputs` (a command never writes onto what it reads, nor onto
    another of its outputs)."""
    for src in inputs:
        if same_file(dest, src):
            raise InputFileError(f"{option} {dest}: names a file this command reads or writes itself ({src}); "
                                 "choose another file")


def refuse_existing(dest: Path, *, overwrite: bool, option: str) -> None:
    """InputFileError naming `option` if `dest` exists and `overwrite` is false: a command never replaces a
    file (another run's report, log or export) without `--overwrite`."""
    dest = Path(dest)
    if overwrite or not (dest.exists() or dest.is_symlink()):
        return
    if dest.is_dir():
        raise InputFileError(f"{option} {dest}: is a directory")
    raise InputFileError(f"{option} {dest}: exists; give --overwrite to replace it or choose another file")


def ensure_dir(path: Path, *, option: str) -> Path:
    """`path` as a directory, created if missing; InputFileError naming `option` if it is a file or cannot be
    created."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise InputFileError(f"{option} {path}: exists and is not a directory")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputFileError(f"{option} {path}: cannot create the directory ({exc.strerror})") from None
    return path


def prepare_output_dir(path: Path, files: Iterable[str], *, overwrite: bool, option: str) -> None:
    """Make `path` ready to receive `files` (names): created if missing; if it holds any of them already
    (an earlier output), refused unless `overwrite`, which removes them first (nothing else in the
    folder is touched, so old and new outputs are never mixed). InputFileError naming `option` if `path`
    is a file or cannot be created."""
    path = ensure_dir(path, option=option)
    present = [name for name in files if (path / name).exists()]
    if not present:
        return
    if not overwrite:
        raise InputFileError(f"{option} {path}: holds an earlier output ({', '.join(present)}); give --overwrite "
                             "to replace it or choose another directory")
    for name in present:
        try:
            (path / name).unlink()
        except OSError as exc:
            raise InputFileError(f"{option} {path}: cannot remove the old {name} ({exc.strerror})") from None


__all__ = ["atomic_path", "ensure_dir", "prepare_output_dir", "refuse_existing", "refuse_inputs", "same_file",
           "write_text_atomic"]
