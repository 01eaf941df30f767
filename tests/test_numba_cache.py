"""Stale compiled kernels (flightrecon/numba_cache.py, drop_stale_kernels): numba keys a cached
kernel on its own file's stamp, so a change to a function it calls in another file would leave
the old compiled code in use, silently.  What is guarded: a source change anywhere a kernel
can reach drops the package's cached kernels once, an unchanged package keeps them, both cache
layouts (beside the sources, NUMBA_CACHE_DIR) are covered, and the folders left out of the
digest hold no kernel."""

import hashlib
import os
from pathlib import Path

from flightrecon import numba_cache as nc

PKG = Path(nc.__file__).resolve().parent


def _fake_package(tmp_path: Path) -> Path:
    pkg = tmp_path / "flightrecon"
    for sub in ("", "methods", "cli"):
        (pkg / sub).mkdir(parents=True, exist_ok=True)
        (pkg / sub / "__init__.py").write_text("")
    (pkg / "methods" / "kern.py").write_text("x = 1\n")
    (pkg / "cli" / "main.py").write_text("y = 1\n")
    return pkg


def _seed(dirs):
    for d in dirs:
        d.mkdir(parents=True, exist_ok=True)
        (d / "kern.f-1.py311.nbi").write_text("index")
        (d / "kern.f-1.py311.1.nbc").write_text("code")


def _cached(dirs):
    return sorted(f.name for d in dirs if d.is_dir() for f in d.glob("*.nb[ic]"))


def test_a_changed_source_drops_the_cached_kernels_once(tmp_path):
    for cache_dir in (None, str(tmp_path / "numba-cache")):
        pkg = _fake_package(tmp_path / ("beside" if cache_dir is None else "user"))
        dirs = nc.kernel_cache_dirs(pkg, cache_dir)
        _seed(dirs)
        # no digest yet (kernels of an unknown source): dropped, digest written
        assert nc.drop_stale_kernels(pkg, cache_dir) is True and _cached(dirs) == []
        _seed(dirs)
        assert nc.drop_stale_kernels(pkg, cache_dir) is False        # unchanged: kept
        assert len(_cached(dirs)) == 2 * len(dirs)
        (pkg / "cli" / "main.py").write_text("y = 2\n")                 # no kernel there
        assert nc.drop_stale_kernels(pkg, cache_dir) is False
        (pkg / "methods" / "kern.py").write_text("x = 2\n")             # a callee changed
        assert nc.drop_stale_kernels(pkg, cache_dir) is True and _cached(dirs) == []


def testnumba_cache_dir_layout_is_numbas():
    """The subfolder names follow numba's UserProvidedCacheLocator: <folder>_<sha1 of path>."""
    from numba.core.caching import UserProvidedCacheLocator

    d = nc.kernel_cache_dirs(PKG, "/some/cache")
    py = str(PKG / "estimation" / "kalman.py")
    sub = UserProvidedCacheLocator.get_suitable_cache_subpath(py)
    assert Path("/some/cache") / sub in d
    path = os.path.abspath(PKG / "estimation")
    assert sub == f"estimation_{hashlib.sha1(path.encode()).hexdigest()}"


def test_the_folders_left_out_of_the_digest_hold_no_kernel():
    import re

    jit = re.compile(r"^\s*@(nb\.|numba\.)?(n?jit|vectorize|guvectorize|cfunc)\b", re.M)
    for sub in nc.NO_KERNEL_DIRS:
        for f in (PKG / sub).rglob("*.py"):
            assert not jit.search(f.read_text()), f


def test_an_unwritable_cache_is_left_alone(tmp_path):
    """A cache folder this process cannot write: no exception, nothing else done."""
    import pytest

    if hasattr(os, "geteuid") and os.geteuid() == 0:
        pytest.skip("running as root: file permissions do not bind")
    pkg = _fake_package(tmp_path)
    dirs = nc.kernel_cache_dirs(pkg, None)
    _seed(dirs)
    os.chmod(dirs[0], 0o500)
    try:
        assert nc.drop_stale_kernels(pkg, None) is False
    finally:
        os.chmod(dirs[0], 0o700)
