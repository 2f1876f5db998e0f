"""Shared fixtures: small meshes and annotation files written into tmp_path."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch
import trimesh
import yaml


def straight_gc(name: str, x0: float, x1: float, radii=(0.9, 0.9), caps=(0.8, 0.8)) -> dict:
    """Annotation dict of a straight GC along the x axis from x0 to x1 with constant radii."""
    return {
        "name": name,
        "curve": {"type": "bezier", "points": [[x0, 0.0, 0.0], [x1, 0.0, 0.0]]},
        "up": [0.0, 0.0, 1.0],
        "keys": [{"t": 0.0, "radii": list(radii), "twist": 0.0}],
        "caps": list(caps),
    }


@pytest.fixture(scope="module")
def single_thread():
    """One torch thread for a module of small tensor ops: on a shared 2-core machine two threads
    contend and run 4-10x slower. Use with pytestmark = pytest.mark.usefixtures(...)."""
    previous = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(previous)


@pytest.fixture
def gc_dict():
    """Factory for straight GC dicts: gc_dict(name, x0, x1, radii=(..), caps=(..))."""
    return straight_gc


@pytest.fixture
def sphere_file(tmp_path) -> Path:
    """A unit icosphere (subdivisions 4) as PLY; normalised with bound 0.8 it has radius ~0.8."""
    path = tmp_path / "sphere.ply"
    trimesh.creation.icosphere(subdivisions=4, radius=1.0).export(path)
    return path


@pytest.fixture
def write_yaml(tmp_path):
    """Factory writing a dict (or raw text) as YAML into tmp_path; returns the path."""

    def write(content, name: str = "shape.yaml") -> Path:
        path = tmp_path / name
        path.write_text(content if isinstance(content, str) else yaml.safe_dump(content, sort_keys=False))
        return path

    return write


@pytest.fixture
def sphere_annotation(sphere_file, write_yaml, gc_dict) -> Path:
    """Annotation YAML of the sphere with one straight GC that covers it."""
    return write_yaml({"name": "sphere", "mesh": sphere_file.name, "normalize": {"bound": 0.8},
                       "gcs": [gc_dict("body", -0.3, 0.3)]})
