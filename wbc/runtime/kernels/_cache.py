"""numba's on-disk cache of the kernels: where it is, when it is stale, when it is cold.

numba keys a cached function on *its own* source file (a content hash of that file, and
the function's bytecode): a callee in another file, or a global constant imported from
another file, is compiled into the caller's machine code but takes no part in the key, so
changing it leaves the caller's cached code stale. :func:`prepare` therefore records a
hash of every source file of the package (and the numba version) next to numba's cache
and, when it differs, deletes the package's cache entries before anything is compiled.

Pure Python: numba is imported only by :func:`cache_dir` (the compiled modules import it
anyway).
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import sys
import types
from collections.abc import Sequence
from pathlib import Path
from typing import TextIO

#: the record of the sources the cached entries were compiled from, in numba's cache directory
STAMP_FILE = "wbc-kernel-sources.sha256"
COLD_MESSAGE = ("wbc: compiling the numba kernels after install, each once when a controller first uses it "
                "(seconds; cached afterwards)")
CHANGED_MESSAGE = ("wbc: the kernel sources or numba changed: recompiling the numba kernels, each when a controller "
                   "first uses it (seconds; cached afterwards)")
NO_CACHE_MESSAGE = ("wbc: numba finds no writable cache directory (the package folder {folder} and the user cache are "
                    "read-only): compiling the numba kernels in memory, seconds at every start; set NUMBA_CACHE_DIR to "
                    "a writable directory to cache them")


def source_stamp(folder: Path, numba_version: str) -> str:
    """sha256 of the numba version and of every ``*.py`` file of ``folder`` (names and contents)."""
    digest = hashlib.sha256(numba_version.encode())
    for path in sorted(folder.glob("*.py")):
        digest.update(b"\0" + path.name.encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()


def cache_dir(source: Path) -> Path | None:
    """The directory where numba caches the functions of the file ``source``, as numba itself
    chooses it (``NUMBA_CACHE_DIR``; else the ``__pycache__`` next to the file when writable;
    else the user-wide cache directory, e.g. ``~/.cache/numba/<folder>_<sha1 of its path>``
    for a read-only site-packages); None when numba cannot cache there at all."""
    try:
        from numba.core.caching import CompileResultCacheImpl

        def probe() -> None:  # pragma: no cover - never called, only located
            pass

        located = types.FunctionType(probe.__code__.replace(co_filename=str(source)), {}, "probe")
        return Path(CompileResultCacheImpl(located).locator.get_cache_path())
    except RuntimeError:  # "cannot cache function": no writable location
        return None
    except Exception:  # noqa: BLE001 - numba's internal API moved: the same rules, written out
        return default_cache_dir(source)


def default_cache_dir(source: Path) -> Path | None:
    """numba's choice of cache directory (its three file-backed locators) written out: the
    fallback of :func:`cache_dir`."""
    from numba.core import config
    from numba.misc.appdirs import AppDirs

    folder = os.path.dirname(os.path.abspath(source))
    subpath = "_".join([os.path.basename(folder), hashlib.sha1(folder.encode()).hexdigest()])
    candidates = ([Path(config.CACHE_DIR) / subpath] if config.CACHE_DIR else []) + [
        Path(folder) / "__pycache__", Path(AppDirs(appname="numba", appauthor=False).user_cache_dir) / subpath]
    for candidate in candidates:
        try:
            candidate.mkdir(parents=True, exist_ok=True)
            if os.access(candidate, os.W_OK):
                return candidate
        except OSError:
            continue
    return None


def first_start(folder: Path, module: str) -> bool:
    """Whether the kernel module ``module`` of the package ``folder`` has no cache index for this
    Python in the directory numba would cache it in -- the first start after an install --
    decided without importing numba (``import wbc`` must not: it is for compiled code only) on
    Linux, where numba's file-backed locators are: ``$NUMBA_CACHE_DIR/<folder>_<sha1 of its path>``,
    else the ``__pycache__`` next to the file when it can be written, else
    ``$XDG_CACHE_HOME/numba/<folder>_<sha1>`` (default ``~/.cache``). False elsewhere, and where no
    such directory can be written (numba compiles in memory there). Nothing is created."""
    if not sys.platform.startswith("linux"):
        return False
    folder = folder.resolve()
    subpath = "_".join([folder.name, hashlib.sha1(str(folder).encode()).hexdigest()])
    root = os.environ.get("NUMBA_CACHE_DIR")
    user = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "numba"
    candidates = ([Path(root) / subpath] if root else []) + [folder / "__pycache__", user / subpath]
    for candidate in candidates:
        existing = next((path for path in (candidate, *candidate.parents) if path.exists()), None)
        if existing is not None and existing.is_dir() and os.access(existing, os.W_OK):
            return is_cold(candidate, (module,))
    return False


def _entries(directory: Path, modules: Sequence[str], suffixes: tuple[str, ...]) -> list[Path]:
    """numba's index (.nbi) and data (.nbc) files of the functions of ``modules`` in
    ``directory`` (numba names them ``<module>.<function>-<line>.py<version>[.<n>].nb?``)."""
    if not directory.is_dir():
        return []
    prefixes = tuple(f"{module}." for module in modules)
    return [path for path in directory.iterdir() if path.name.startswith(prefixes) and path.name.endswith(suffixes)]


def invalidate(directory: Path, stamp: str, modules: Sequence[str]) -> bool:
    """Delete the cache entries of ``modules`` in ``directory`` unless they were compiled from
    the sources of ``stamp`` (recorded in :data:`STAMP_FILE`); record ``stamp``. Returns
    whether entries were deleted."""
    record = directory / STAMP_FILE
    try:
        if record.read_text().strip() == stamp:
            return False
    except OSError:
        pass
    stale = _entries(directory, modules, (".nbi", ".nbc"))
    for path in stale:
        try:
            path.unlink()
        except FileNotFoundError:
            pass
    temporary = directory / f"{STAMP_FILE}.{os.getpid()}"
    try:
        directory.mkdir(parents=True, exist_ok=True)
        temporary.write_text(stamp + "\n")
        os.replace(temporary, record)
    except OSError:  # not writable: numba cannot cache here either, nothing stale can be loaded
        pass
    return bool(stale)


def is_cold(directory: Path, modules: Sequence[str]) -> bool:
    """Whether some module of ``modules`` has no index file for this Python in ``directory``
    (its kernels will be compiled, not loaded)."""
    tag = f".py{sys.version_info[0]}{sys.version_info[1]}{getattr(sys, 'abiflags', '')}.nbi"
    indexed = {path.name.split(".", 1)[0] for path in _entries(directory, modules, (tag,))}
    return not set(modules) <= indexed


def prepare(folder: Path, modules: Sequence[str], stream: TextIO | None = None,
            cold: Sequence[str] | None = None) -> Path | None:
    """Before the modules ``modules`` of the package ``folder`` are imported (their kernels
    compile or load at import): drop stale cache entries (:func:`invalidate`) and, when
    something will be compiled (a module of ``cold``, default ``modules``, has no cache index),
    say so in one line on ``stream`` (default stderr). Returns
    numba's cache directory for the package; None, said on ``stream``, when numba has nowhere
    to write one (the kernels must then be compiled with ``cache=False``: numba refuses
    ``cache=CACHE`` there)."""
    import numba

    directory = cache_dir(folder / f"{modules[0]}.py")
    if directory is None:
        print(NO_CACHE_MESSAGE.format(folder=folder), file=stream or sys.stderr, flush=True)
        return None
    changed = invalidate(directory, source_stamp(folder, numba.__version__), modules)
    if is_cold(directory, modules if cold is None else cold):
        print(CHANGED_MESSAGE if changed else COLD_MESSAGE, file=stream or sys.stderr, flush=True)
    return directory


def write_generated(directory: Path, prefix: str, source: str) -> Path | None:
    """``source`` as the file ``directory/<prefix><sha256 of source>.py`` (written once, so its
    stamp, which numba's cache index checks, never changes), the other ``<prefix>*.py`` files of
    ``directory`` and their numba entries deleted (generated from other sources); None when
    ``directory`` cannot be written."""
    path = directory / f"{prefix}{hashlib.sha256(source.encode()).hexdigest()[:20]}.py"
    try:
        if not (path.is_file() and path.read_text() == source):
            temporary = path.with_name(f"{path.name}.{os.getpid()}")
            temporary.write_text(source)
            os.replace(temporary, path)
    except OSError:
        return None
    for other in directory.glob(f"{prefix}*.py"):
        if other != path:
            entries = cache_dir(other)
            for stale in [other, *(_entries(entries, (other.stem,), (".nbi", ".nbc")) if entries else [])]:
                try:
                    stale.unlink()
                except OSError:
                    pass
    return path


def load_generated(directory: Path | None, prefix: str, source: str, name: str) -> types.ModuleType:
    """The module of the generated ``source``: imported from its file in ``directory``
    (:func:`write_generated`: numba caches what is compiled from it next to it), or built in memory
    (``__file__`` unset; nothing of it can be cached) when ``directory`` is None or not writable."""
    path = write_generated(directory, prefix, source) if directory is not None else None
    if path is None:
        module = types.ModuleType(name)
        exec(compile(source, f"<{name}>", "exec"), module.__dict__)  # noqa: S102 -- generated by wbc
        return module
    spec = importlib.util.spec_from_file_location(path.stem, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[path.stem] = module
    spec.loader.exec_module(module)
    return module
