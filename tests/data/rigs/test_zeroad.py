"""0 A.D. readers, rigs, the structural joint map and the collection builder, on tiny files the
tests write themselves (tests/data/rigs/small_zeroad.py): no downloaded package."""
from __future__ import annotations

import json
import shutil
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import trimesh
import pytest

from ngc_gen.data.errors import DataError
from ngc_gen.data.rigs.rig import quat_matrices
from ngc_gen.data.rigs.skeleton_map import load_joint_map, structure_map
from ngc_gen.data.rigs.zeroad_formats import read_pmd, read_psa, read_skeletons
from ngc_gen.data.rigs.zeroad_rig import choose_skeleton, pmd_rig, quat_mul

from .small_zeroad import (EXPECTED, NAMES, PARENT, POS, mesh_arrays, pmd_bytes, psa_bytes,
                           quat_y, skeleton_xml)


@pytest.fixture
def rig(tmp_path):
    (tmp_path / "tiny.pmd").write_bytes(pmd_bytes())
    skel = read_skeletons(skeleton_xml())[0]
    return pmd_rig(read_pmd(tmp_path / "tiny.pmd"), skel)


def _names(rig, jm):
    return {g: [rig.names[j] for j in r["chain"]] for g, r in jm.resolved.items()}


def test_pmd_and_skeleton_read_back_and_rest_pose_is_the_bind_pose(rig):
    V, F, bone = mesh_arrays()
    assert np.allclose(rig.vertices, V, atol=1e-6) and (rig.faces == F).all()
    # the file's clockwise triangles come out facing outward: a closed piece has positive
    # volume (the winding numbers of the proxy and of transfer count it as solid)
    assert trimesh.Trimesh(rig.vertices, rig.faces, process=False).volume > 0
    assert (rig.skin_joints[:, 0] == bone).all() and np.allclose(rig.skin_weights.sum(1), 1)
    assert rig.names == NAMES and (rig.parent == PARENT).all()
    assert np.allclose(rig.joint_positions(), POS, atol=1e-6)
    assert np.allclose(rig.posed(), V, atol=1e-6)


def test_a_psa_clip_poses_the_mesh_by_its_model_space_frames(tmp_path, rig):
    # frame 1: the whole animal turned 90 degrees about +y, and moved by (1, 0, 0)
    q = np.tile([0.0, 0.0, 0.0, 1.0], (2, len(NAMES), 1))
    t = np.stack([POS, POS])
    R = quat_matrices(quat_y(90.0))
    q[1] = quat_mul(np.broadcast_to(quat_y(90.0), q[1].shape), q[1])
    t[1] = POS @ R.T + [1.0, 0.0, 0.0]
    (tmp_path / "turn.psa").write_bytes(psa_bytes(t, q, "turn", frame_ms=500.0))
    psa = read_psa(tmp_path / "turn.psa")
    assert psa.name == "turn" and psa.frame_length == pytest.approx(0.5)
    skel = read_skeletons(skeleton_xml())[0]
    posed = pmd_rig(read_pmd(tmp_path / "tiny.pmd"), skel, {"turn": psa})
    assert np.allclose(posed.posed("turn", 0.0), rig.vertices, atol=1e-5)
    assert np.allclose(posed.posed("turn", 0.5), rig.vertices @ R.T + [1, 0, 0], atol=1e-5)


@pytest.mark.parametrize("kind", ["pmd", "psa"])
def test_truncated_or_foreign_files_are_one_line_errors_naming_the_file(tmp_path, kind):
    good = pmd_bytes() if kind == "pmd" else psa_bytes(np.zeros((2, 3, 3)), np.zeros((2, 3, 4)))
    magic = "PSMD" if kind == "pmd" else "PSSA"
    read = read_pmd if kind == "pmd" else read_psa
    for data, says in ((good[:-20], "truncated"), (b"GIF89a" + good[6:], magic),
                       (good[:10], "truncated")):
        path = tmp_path / f"bad.{kind}"
        path.write_bytes(data)
        with pytest.raises(DataError) as e:
            read(path)
        msg = str(e.value)
        assert "\n" not in msg and str(path) in msg and says in msg and kind.upper() in msg


def test_bad_skeleton_xml_is_one_line(tmp_path):
    (tmp_path / "s.xml").write_text("<skeletons><standard_skeleton")
    with pytest.raises(DataError, match="not a valid skeleton XML"):
        read_skeletons(tmp_path / "s.xml")


def test_the_skeleton_whose_tree_joins_the_bones_closest_is_chosen(tmp_path):
    right = read_skeletons(skeleton_xml())[0]
    shuffled = np.roll(PARENT, 3)
    shuffled[0] = -1
    shuffled = np.where(shuffled >= np.arange(len(PARENT)), 0, shuffled)  # still a tree
    wrong = read_skeletons(skeleton_xml(parent=shuffled, sid="Other"))[0]
    pmd = read_pmd(pmd_bytes(), "tiny.pmd")
    assert choose_skeleton(pmd, [wrong, right]).id == "Tiny"
    with pytest.raises(DataError, match="no standard skeleton has its 17 bones"):
        choose_skeleton(pmd, [read_skeletons(skeleton_xml(NAMES[:3], PARENT[:3]))[0]])


def test_structure_maps_legs_sides_neck_head_tail_from_geometry(rig):
    jm = structure_map(rig)
    names = _names(rig, jm)
    for gc, chain in EXPECTED.items():
        assert names[gc] == chain, gc
    assert names["torso"] == ["root", "spine", "chest"]
    assert np.allclose(jm.up, [0, 1, 0]) and np.allclose(jm.front, [0, 0, -1], atol=1e-6)
    owned = sorted(j for r in jm.resolved.values() for j in r["skinned"])
    assert owned == list(range(len(NAMES)))  # every bone skinned to exactly one GC


def _rig_with_tail_joint(name: str, at: list[float]):
    """The test rig with a joint `name` at `at` between the root and the tail, the tail's
    parent."""
    i = NAMES.index("tail")
    names = NAMES[:i] + [name] + NAMES[i:]
    parent = np.r_[PARENT[:i], 0, i, i + 1]
    pos = np.vstack([POS[:i], at, POS[i:]])
    skel = read_skeletons(skeleton_xml(names, parent))[0]
    return pmd_rig(read_pmd(pmd_bytes(pos), f"{name}.pmd"), skel)


def test_a_pelvis_the_tail_hangs_from_inside_the_hips_is_the_torsos(tmp_path):
    # a pelvis bone between the hips and the tail, in front of the back legs' tops: it moves
    # the rump (in 0 A.D. also the armour over it), so it is the torso's, on its curve, and
    # the tail starts at the first joint past the back legs
    rig = _rig_with_tail_joint("pelvis", [0.0, 2.1, 0.75])
    jm = structure_map(rig)
    chains = _names(rig, jm)
    assert chains["tail"] == ["tail", "tail_tip"]
    assert chains["torso"] == ["pelvis", "root", "spine", "chest"]
    skinned = {g: sorted(rig.names[j] for j in r["skinned"]) for g, r in jm.resolved.items()}
    assert "pelvis" in skinned["torso"] and skinned["tail"] == ["tail", "tail_tip"]


@pytest.mark.parametrize("wide", [True, False])
def test_a_tail_joint_whose_skin_spans_the_rump_is_the_torsos(wide):
    # a spine end just past the back legs' tops that the tail hangs from: when the vertices
    # its skin holds span the body's width there (the top of the rump: 0 A.D.'s cattle), it is
    # the torso's and the tail starts after it; when they are a tail's narrow tube, it stays
    # the tail's first joint
    rig = _rig_with_tail_joint("rump", [0.0, 2.05, 1.15])
    at = NAMES.index("tail")
    if wide:  # the rump's cube stretched across the body, wider than the hind legs stand
        rig.vertices[rig.skin_joints[:, 0] == at, 0] *= 6.0
    jm = structure_map(rig)
    chains = _names(rig, jm)
    skinned = {g: sorted(rig.names[j] for j in r["skinned"]) for g, r in jm.resolved.items()}
    if wide:
        assert chains["tail"] == ["tail", "tail_tip"] and chains["torso"][0] == "rump"
        assert "rump" in skinned["torso"] and skinned["tail"] == ["tail", "tail_tip"]
    else:
        assert chains["tail"] == ["rump", "tail", "tail_tip"]
        assert "rump" not in chains["torso"] and "rump" in skinned["tail"]


def test_an_unskinned_root_on_the_ground_is_no_part_of_the_torsos_curve():
    # the front legs and the neck hang from a joint that carries no skin and sits on the
    # ground under the chest (0 A.D.'s sheep root): the torso's curve ends at the chest, not
    # down at the ground
    at = NAMES.index("neck")
    names = NAMES[:at] + ["base"] + NAMES[at:]
    parent = np.array([-1 if p < 0 else p + (p >= at) for p in PARENT])
    parent = np.r_[parent[:at], at - 1, parent[at:]]
    for child in ("neck", "r_arm", "l_arm"):
        parent[names.index(child)] = at
    pos = np.vstack([POS[:at], [0.0, 0.05, -1.0], POS[at:]])
    skel = read_skeletons(skeleton_xml(names, parent))[0]
    rig = pmd_rig(read_pmd(pmd_bytes(pos), "base.pmd"), skel)
    rig.skin_joints[rig.skin_joints == at] = names.index("chest")  # its cube is the chest's
    chains = _names(rig, structure_map(rig))
    assert chains["torso"] == ["root", "spine", "chest"]
    assert chains["leg_fl"] == EXPECTED["leg_fl"] and chains["tail"] == EXPECTED["tail"]


def _turned(rig, R):
    """The rig with its whole body turned by R (3, 3) about the origin."""
    from ngc_gen.data.rigs.rig import matrix_trs

    M = np.eye(4)
    M[:3, :3] = R
    root = int(np.flatnonzero(rig.parent < 0)[0])
    local = np.eye(4)
    local[:3, :3] = quat_matrices(rig.rotation[root])
    local[:3, 3] = rig.translation[root]
    t, q, _ = matrix_trs(M @ local)
    rig.translation[root], rig.rotation[root] = t, q
    rig.inverse_bind = rig.inverse_bind @ np.linalg.inv(M)
    rig.vertices = rig.vertices @ R.T
    return rig


def test_structure_map_finds_the_same_parts_turned_any_way(rig):
    R = np.linalg.qr(np.random.default_rng(3).normal(size=(3, 3)))[0]
    R *= np.sign(np.linalg.det(R))
    turned = _turned(rig, np.array([[0, 0, 1], [1, 0, 0], [0, 1, 0.0]]))  # y up -> z up
    jm = structure_map(turned)
    assert np.allclose(jm.up, [0, 0, 1]) and _names(turned, jm)["leg_fl"] == EXPECTED["leg_fl"]
    jm = structure_map(_turned(turned, R), up=R @ [0, 0, 1.0])  # any direction, up given
    for gc, chain in EXPECTED.items():
        assert _names(turned, jm)[gc] == chain, gc


def test_a_skeleton_without_four_legs_on_the_ground_is_refused(tmp_path):
    pos = POS.copy()
    pos[[7, 10], 1] = 1.2  # the front hooves lifted: two chains reach the ground
    skel = read_skeletons(skeleton_xml())[0]
    lifted = pmd_rig(read_pmd(pmd_bytes(pos), "lifted.pmd"), skel)
    with pytest.raises(DataError) as e:
        structure_map(lifted, up=[0, 1, 0])
    assert "2 chains reach the ground, a quadruped has 4" in str(e.value)
    assert "lifted.pmd" in str(e.value) and "\n" not in str(e.value)


def test_a_joint_map_file_is_the_users_fallback(tmp_path, rig):
    from ngc_gen.data.autogc.template import load_template

    template = load_template(Path(__file__).parents[3] / "datasets/animals/quadruped.yaml")
    jm = structure_map(rig, template)
    path = tmp_path / "map.yaml"
    import yaml

    path.write_text(yaml.safe_dump(jm.names(rig)))
    back = load_joint_map(path, rig, template)
    assert back.resolved == jm.resolved and np.allclose(back.front, jm.front)
    d = jm.names(rig)
    del d["tail"]
    path.write_text(yaml.safe_dump(d))
    with pytest.raises(DataError, match="GC 'tail'.*no entry"):
        load_joint_map(path, rig, template)


def _package(tmp_path: Path) -> Path:
    """A tiny 0ad-data .deb: public.zip holding the quadruped, a fish-like mesh without legs,
    a truncated mesh, a skeleton, a clip and a fauna actor naming the clip."""
    zpath = tmp_path / "public.zip"
    finned = POS.copy()
    finned[[7, 10, 12, 14], 1] = 1.5  # no chain reaches the ground
    q = np.tile([0.0, 0.0, 0.0, 1.0], (3, len(NAMES), 1))
    with zipfile.ZipFile(zpath, "w", zipfile.ZIP_STORED) as z:
        z.writestr("art/meshes/skeletal/tiny_horse.dae.cached.pmd", pmd_bytes())
        z.writestr("art/meshes/skeletal/tiny_fish.dae.cached.pmd", pmd_bytes(finned))
        z.writestr("art/meshes/skeletal/tiny_cut.dae.cached.pmd", pmd_bytes()[:-20])
        z.writestr("art/skeletons/tiny.xml", skeleton_xml())
        z.writestr("art/animation/quadraped/tiny_walk.dae.cached.psa",
                   psa_bytes(np.stack([POS] * 3), q, "walk"))
        z.writestr("art/actors/fauna/tiny.xml", '<actor><group><variant><mesh>skeletal/'
                   'tiny_horse.dae</mesh></variant></group><group><variant file="quadraped/'
                   'tiny.xml"/></group></actor>')
        z.writestr("art/variants/quadraped/tiny.xml", '<variant><animations><animation '
                   'file="quadraped/tiny_walk.dae" name="Walk"/></animations></variant>')
        z.writestr("art/textures/skins/big.png", b"x" * 5000)
    root = tmp_path / "pkg"
    inside = root / "usr/share/games/0ad/mods/public"
    inside.mkdir(parents=True)
    shutil.move(zpath, inside / "public.zip")
    (root / "DEBIAN").mkdir()
    (root / "DEBIAN/control").write_text("Package: 0ad-data\nVersion: 0.0.26-1\nArchitecture: all\n"
                                         "Maintainer: t <t@t>\nDescription: t\n")
    deb = tmp_path / "0ad-data_0.0.26-1_all.deb"
    subprocess.run(["dpkg-deb", "--build", "-Zgzip", str(root), str(deb)], check=True,
                   capture_output=True)
    return deb


@pytest.mark.skipif(shutil.which("dpkg-deb") is None, reason="needs dpkg-deb")
def test_builder_streams_the_package_keeps_quadrupeds_and_never_deletes_a_users_file(tmp_path):
    from ngc_gen.data.rigs.zeroad import zeroad_quadrupeds

    deb = _package(tmp_path)
    meshes = zeroad_quadrupeds(tmp_path / "cache", deb=deb, download=False)
    assert [m.name for m in meshes] == ["tiny_horse"] and deb.is_file()
    m = meshes[0]
    assert m.species == "tiny" and list(m.rig.clips) == ["tiny_walk"]
    assert _names(m.rig, m.joint_map)["leg_fl"] == EXPECTED["leg_fl"]
    out = tmp_path / "cache/zeroad-0.0.26"
    manifest = json.loads((out / "manifest.json").read_text())
    assert "chains reach the ground" in manifest["refused"]["tiny_fish"]
    assert "truncated" in manifest["refused"]["tiny_cut"]  # refused alone, the rest kept
    kept = sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file())
    assert kept == ["art/animation/quadraped/tiny_walk.dae.cached.psa",
                    "art/meshes/skeletal/tiny_horse.dae.cached.pmd", "art/skeletons/tiny.xml",
                    "manifest.json"]
    deb.unlink()  # built once: the cache answers without the package
    assert [m.name for m in zeroad_quadrupeds(tmp_path / "cache", download=False)] == ["tiny_horse"]
    # a user's map file for the skeleton replaces the structure's map
    import yaml

    d = m.joint_map.names(m.rig)
    d["tail"] = {"joints": ["tail"], "skinned": ["tail", "tail_tip"]}
    (tmp_path / "maps").mkdir()
    (tmp_path / "maps/Tiny.yaml").write_text(yaml.safe_dump(d))
    m2 = zeroad_quadrupeds(tmp_path / "cache", download=False, maps=tmp_path / "maps")[0]
    assert _names(m2.rig, m2.joint_map)["tail"] == ["tail"]
    assert m2.joint_map.source.endswith("Tiny.yaml")


def test_no_package_and_no_download_says_what_to_run(tmp_path, monkeypatch):
    from ngc_gen.data.rigs.zeroad import DEB_ENV, zeroad_quadrupeds

    monkeypatch.delenv(DEB_ENV, raising=False)
    with pytest.raises(DataError, match="apt-get download 0ad-data"):
        zeroad_quadrupeds(tmp_path, download=False)


def test_rig_gcs_of_a_zeroad_mesh_follow_its_structure_in_its_own_frame(rig):
    from ngc_gen.data.autogc.template import load_template
    from ngc_gen.data.rigs.rig_gcs import RigGCSettings
    from ngc_gen.data.rigs.zeroad import UP, ZeroADMesh

    template = load_template(Path(__file__).parents[3] / "datasets/animals/quadruped_transfer.yaml")
    mesh = ZeroADMesh("tiny", "tiny", "Tiny", rig, structure_map(rig, None, UP))
    ps = mesh.pose(template, settings=RigGCSettings.from_yaml(resolution=48, samples=2000,
                                                    check_samples=4000))
    assert ps.coverage >= 0.999 and [g["name"] for g in ps.gcs] == template.names
    ends = {g["name"]: np.asarray(g["curve"]["points"])[[0, -1]] for g in ps.gcs}
    assert ends["leg_fl"][:, 0].mean() < 0 < ends["leg_fr"][:, 0].mean()  # its left is -x
    assert ends["head"][:, 2].mean() < ends["torso"][:, 2].mean() < ends["tail"][:, 2].mean()
    # the template's frame (y up, +z front) turned into the rig's (y up, -z front)
    up = {g["name"]: np.asarray(g["up"]) for g in ps.gcs}
    assert np.allclose(up["leg_fl"], [0, 0, -1]) and np.allclose(up["torso"], [0, 1, 0])
