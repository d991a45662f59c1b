"""numba's on-disk cache for the kernels of this folder, kept fresh across files.

numba stamps a cached function with the hash of its own source file only, so a kernel that
calls (and inlines) a jitted helper of another file would keep stale machine code after that
helper changed. The locators below give every function defined in ``spinweb_fe/fe/`` one
stamp: the hash of every module of the folder and its subfolders (``hub/``, ``coil/``,
``contact/``). An edit anywhere in ``fe/`` recompiles every ``fe`` kernel once; anything
else keeps numba's own locators. This lets a feature live in a file of its own (contact,
the hub, the coil) while the step loop calls it.

Installed when ``spinweb_fe.fe`` is imported, before any of its kernels is defined.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

from numba.core import caching

FOLDER = Path(__file__).resolve().parent
_memo: dict = {}


def folder_stamp(folder: Path = FOLDER) -> str:
    """sha256 over the paths (relative to ``folder``) and contents of every ``*.py`` file of
    ``folder`` and its subfolders (memoised on their sizes and modification times)."""
    files = sorted(folder.rglob("*.py"))
    key = (str(folder), tuple((str(p), p.stat().st_mtime_ns, p.stat().st_size) for p in files))
    if key not in _memo:
        h = hashlib.sha256()
        for p in files:
            h.update(p.relative_to(folder).as_posix().encode())
            h.update(b"\0")
            h.update(p.read_bytes())
        _memo[key] = h.hexdigest()
    return _memo[key]


def _in_folder(py_file) -> bool:
    """The file lies in fe/ or one of its subfolders."""
    try:
        return FOLDER in Path(py_file).resolve().parents
    except OSError:
        return False


def _locator(base):
    class FolderStampLocator(base):
        """``base`` (a numba cache locator) with the stamp of the whole fe/ folder."""

        def get_source_stamp(self):
            return folder_stamp()

        @classmethod
        def from_function(cls, py_func, py_file):
            if not _in_folder(py_file):
                return None
            return super().from_function(py_func, py_file)

    FolderStampLocator.__name__ = f"FolderStamp{base.__name__.lstrip('_')}"
    return FolderStampLocator


def install() -> bool:
    """Put the folder-stamp locators in front of numba's own (once). False if this numba
    does not have the locator classes (then each file keeps its own stamp)."""
    impl = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl", None)
    bases = [getattr(caching, name, None) or getattr(caching, "_" + name, None)
             for name in ("UserProvidedCacheLocator", "InTreeCacheLocator")]
    if impl is None or not all(bases) or not hasattr(impl, "_locator_classes"):
        return False
    if any(getattr(c, "__name__", "").startswith("FolderStamp") for c in impl._locator_classes):
        return True
    impl._locator_classes[:0] = [_locator(b) for b in bases]
    return True


INSTALLED = install()
