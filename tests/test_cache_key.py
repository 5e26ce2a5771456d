"""The numba cache folder is keyed on the kernel modules only."""

from __future__ import annotations

import masonry_nscd


def test_kernel_hash_ignores_modules_without_kernels(tmp_path, monkeypatch):
    (tmp_path / "kernels.py").write_text("from numba import njit\n")
    (tmp_path / "cli.py").write_text("print('a')\n")
    monkeypatch.setattr(masonry_nscd, "_PKG", tmp_path)
    kernels, everything = masonry_nscd.source_hash(True), masonry_nscd.source_hash()
    (tmp_path / "cli.py").write_text("print('b')\n")
    assert masonry_nscd.source_hash(True) == kernels
    assert masonry_nscd.source_hash() != everything
    (tmp_path / "kernels.py").write_text("from numba import njit  # edited\n")
    assert masonry_nscd.source_hash(True) != kernels
