"""Edits seen through extracted meshes (the exactness tests), with a real NGCDecoder whose
weights make a closed tube field (conftest), so no fitting is needed."""
import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from ngc_gen.edit import move_points, rigid, scale_radii, stretch, twist
from ngc_gen.eval import chamfer
from ngc_gen.extract import Grid
from ngc_gen.shape import Shape

from .conftest import surface_points

RES = 72


def mesh_of(module, gcs, res=RES, mixes=None):
    codes = module.codes.weight[:len(gcs)].detach()
    return Shape(gcs, codes, module.decoder, mixes=mixes).mesh(res).mesh


@pytest.fixture(scope="module")
def base_mesh(module):
    from .conftest import GC_DICTS
    from ngc_gen.geometry import GeneralizedCylinder

    return mesh_of(module, [GeneralizedCylinder.from_dict(d) for d in GC_DICTS])


def test_identity_edits_give_the_same_mesh(module, gcs, base_mesh):
    assert base_mesh.is_watertight and base_mesh.volume > 0
    edited = [twist(scale_radii(move_points(g, [0, 1], [0, 0, 0]), None, 1.0), 0.5, 0.0)
              for g in gcs]
    edited[0] = stretch(edited[0], 0.0, 1.0, 1.0)
    m = mesh_of(module, edited)
    assert np.array_equal(m.faces, base_mesh.faces)
    np.testing.assert_allclose(m.vertices, base_mesh.vertices, atol=1e-6)
    assert chamfer(surface_points(m), surface_points(base_mesh)) < 1e-6


def test_full_turn_twist_equals_no_twist(module, gcs, base_mesh):
    m = mesh_of(module, [twist(g, None, 360.0) for g in gcs])
    assert chamfer(surface_points(m), surface_points(base_mesh)) < 1e-6


def test_rigid_motion_of_every_gc_moves_the_mesh_rigidly(module, gcs, base_mesh):
    R = Rotation.from_rotvec([0.3, -0.5, 0.8]).as_matrix()
    t = np.array([0.05, -0.1, 0.08])
    m = mesh_of(module, [rigid(g, R, t) for g in gcs])
    h = Grid(RES, 1.0).spacing
    moved = surface_points(base_mesh) @ R.T + t
    cd = chamfer(surface_points(m), moved)
    assert cd < h ** 2, (cd, h ** 2)
    assert m.volume == pytest.approx(base_mesh.volume, rel=0.02)


def section_area(mesh, origin, normal) -> float:
    """Area of the plane section of a closed, outward-oriented mesh: the section's segments
    oriented counterclockwise about `normal` (region on their left), then the shoelace sum."""
    from trimesh.intersections import mesh_plane

    n = np.asarray(normal, float) / np.linalg.norm(normal)
    seg, faces = mesh_plane(mesh, n, origin, return_faces=True)
    a, b = seg[:, 0] - origin, seg[:, 1] - origin
    outward = mesh.face_normals[faces]
    flip = np.einsum("ij,ij->i", np.cross(n, b - a), outward) > 0  # left side must be inside
    a, b = np.where(flip[:, None], b, a), np.where(flip[:, None], a, b)
    return 0.5 * float((np.cross(a, b) @ n).sum())


@pytest.fixture(scope="module")
def body_meshes(module):
    """The body alone and the whole shape at resolution 80 (references for the scale test)."""
    from .conftest import GC_DICTS
    from ngc_gen.geometry import GeneralizedCylinder

    gcs = [GeneralizedCylinder.from_dict(d) for d in GC_DICTS]
    return mesh_of(module, gcs[:1], res=80), mesh_of(module, gcs, res=80)


@pytest.mark.parametrize("s", [0.7, 1.3])
def test_scaling_radii_scales_cross_section_area_by_s_squared(module, gcs, body_meshes, s):
    body, ref = body_meshes
    m = mesh_of(module, [scale_radii(gcs[0], None, s), *gcs[1:]], res=80)
    for x in (-0.3, -0.1):  # cross-sections of the body away from the other GCs
        a0 = section_area(ref, np.array([x, 0, 0.0]), [1, 0, 0])
        assert a0 > 0.01
        assert section_area(m, np.array([x, 0, 0.0]), [1, 0, 0]) == pytest.approx(s ** 2 * a0,
                                                                                  rel=0.04)
    # a single GC (caps included): the volume scales by s^2 too
    assert mesh_of(module, [scale_radii(gcs[0], None, s)], res=80).volume == \
        pytest.approx(s ** 2 * body.volume, rel=0.03)


def test_local_stretch_carries_the_neural_field_along(module, gcs):
    """The stretched piece holds the features of its t-range: the mesh length grows by
    (f - 1) times the piece, and the field at a point of the stretched piece equals the field
    at the point it came from (same relative coordinates)."""
    body = gcs[0]
    s = stretch(body, 0.3, 0.6, 2.0)
    codes = module.codes.weight[:1].detach()
    fn = Shape([body], codes, module.decoder).gc_sdf
    rng = np.random.default_rng(0)
    rel = np.stack([rng.uniform(-0.4, 0.2, 500), rng.uniform(-1, 1, 500),
                    rng.uniform(-1, 1, 500)], 1)
    before = body.to_world(rel)
    after = s.to_world(rel)
    rel_after = torch.as_tensor(s.to_relative(after), dtype=torch.float32)
    rel_before = torch.as_tensor(body.to_relative(before), dtype=torch.float32)
    torch.testing.assert_close(fn(0, rel_after), fn(0, rel_before), atol=1e-5, rtol=0)
