"""Limits from the machine (ngc_gen/extract/budget.py): a resolution whose grid does not fit in
the memory available is refused before anything is allocated, naming the largest that fits."""
import subprocess
import sys

import pytest

from ngc_gen.extract import budget, extract_mesh, per_gc_rows
from ngc_gen.extract.budget import (GridTooLarge, check_resolution, extraction_bytes,
                                    largest_resolution)

from .conftest import sphere_sdf, straight_gc, through_gcs


@pytest.mark.parametrize("method,keep", [("sparse", False), ("prefiltered", False),
                                         ("sparse", True)])
def test_largest_resolution_is_the_largest_that_fits(method, keep):
    for available in (1 << 30, 16 << 30, 128 << 30):
        r = largest_resolution(available, method, keep)
        assert extraction_bytes(r, method, keep) <= available
        assert extraction_bytes(r + 1, method, keep) > available
    assert largest_resolution(10 << 30, "sparse") > largest_resolution(10 << 30, "prefiltered")


def test_a_grid_that_does_not_fit_is_refused_with_the_largest_that_does():
    with pytest.raises(GridTooLarge) as e:
        check_resolution(100_000, available=64 << 30, what="extract.resolution")
    largest = largest_resolution(int(budget.USABLE * (64 << 30)))
    assert e.value.largest == largest and 256 < largest < 100_000
    assert f"the largest resolution that fits is {largest}" in str(e.value)
    check_resolution(largest, available=64 << 30)  # the one it names passes


def test_available_memory_is_read_from_the_machine():
    assert 0 < budget.available_bytes() < 1 << 50


def test_extract_mesh_refuses_before_allocating(monkeypatch):
    gc = straight_gc([-0.5, 0, 0], [0.5, 0, 0], 0.2)
    rows = per_gc_rows(through_gcs([gc], [sphere_sdf([0, 0, 0], 0.3)]))
    assert len(extract_mesh([gc], rows, 16).mesh.faces) > 0
    monkeypatch.setattr(budget, "available_bytes", lambda: 1 << 20)  # a 1 MiB machine
    with pytest.raises(GridTooLarge, match="largest resolution that fits is"):
        extract_mesh([gc], rows, 64)  # would need ~16 MB: refused


def test_the_check_imports_no_torch():
    code = ("import sys; from ngc_gen.extract.budget import check_resolution; "
            "check_resolution(64); assert 'torch' not in sys.modules and 'numpy' not in "
            "sys.modules")
    subprocess.run([sys.executable, "-c", code], check=True)
