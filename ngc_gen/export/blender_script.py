"""Run inside Blender (`blender -b --python blender_script.py -- <glb> <out.npz> <t0,t1,...>`):
import the GLB with Blender's own glTF importer and save what it made (armatures and their bone
names, meshes and their armature binding, actions, shape keys) and the evaluated mesh (armature
and shape keys applied) at the given clip times, in glTF's axes (y up). Not imported by ngc_gen:
Blender's Python runs it."""
import json
import sys

import numpy

if not hasattr(numpy, "bool"):  # Blender 3.4's importer still says numpy.bool (numpy >= 1.24)
    numpy.bool = bool

import bpy  # noqa: E402


def main():
    glb, out, times = sys.argv[sys.argv.index("--") + 1:][:3]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.fps, scene.render.fps_base = 24, 1.0
    bpy.ops.import_scene.gltf(filepath=glb)
    arms = [o for o in scene.objects if o.type == "ARMATURE"]
    meshes = [o for o in scene.objects if o.type == "MESH"]
    info = {"armatures": len(arms), "bones": [b.name for b in arms[0].data.bones] if arms else [],
            "meshes": len(meshes), "actions": [a.name for a in bpy.data.actions]}
    mesh = meshes[0]
    mods = [m for m in mesh.modifiers if m.type == "ARMATURE"]
    info["bound"] = bool(mods) and mods[0].object is not None and mods[0].object in arms
    keys = mesh.data.shape_keys
    info["shape_keys"] = [k.name for k in keys.key_blocks][1:] if keys else []
    # play the clip: the importer puts each action on its object (NLA when several)
    for o in arms + meshes:
        ad = o.animation_data or (o.data.shape_keys.animation_data if o.type == "MESH"
                                  and o.data.shape_keys else None)
        if o.animation_data and o.animation_data.action is None and o.animation_data.nla_tracks:
            o.animation_data.action = o.animation_data.nla_tracks[0].strips[0].action
        if o.type == "MESH" and keys and keys.animation_data and keys.animation_data.action is None \
                and keys.animation_data.nla_tracks:
            keys.animation_data.action = keys.animation_data.nla_tracks[0].strips[0].action
    frames = {}
    for t in [float(x) for x in times.split(",")]:
        f = t * scene.render.fps
        scene.frame_set(int(numpy.floor(f)), subframe=float(f - numpy.floor(f)))
        dg = bpy.context.evaluated_depsgraph_get()
        ev = mesh.evaluated_get(dg)
        m = ev.to_mesh()
        co = numpy.empty(len(m.vertices) * 3)
        m.vertices.foreach_get("co", co)
        co = co.reshape(-1, 3)
        w = numpy.array(mesh.matrix_world)
        co = co @ w[:3, :3].T + w[:3, 3]
        ev.to_mesh_clear()
        frames[repr(t)] = numpy.stack([co[:, 0], co[:, 2], -co[:, 1]], 1)  # z up -> y up
    numpy.savez(out, info=json.dumps(info), times=list(frames),
                **{f"v{i}": v for i, v in enumerate(frames.values())})


main()
