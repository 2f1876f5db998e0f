"""The editor in the browser: a viser server on an `EditorSession` (docs/editor.md).

Scene: the shape's mesh, its GCs drawn translucent, every control point as a dot and the
selected GC's control points as draggable handles (transform controls). Panel: GC and key
choice, radius and twist sliders, stretch, pose, part mixing, sample / A<->B interpolation for a
generation run, undo / redo, save program, export mesh (PLY) or glb (a rigged glTF through
`ngc_gen.export`), and a message line. Each control calls one session interaction; the session accepts or refuses it (the message says why) and the scene
and controls are then set from the session's state, so a refused drag or slider springs back to
the last valid shape. Callbacks never raise: the server outlives any interaction.
"""
from __future__ import annotations

import functools
import threading
import time
from pathlib import Path

import numpy as np

from ngc_gen import workspace
from ngc_gen.viz.gc_mesh import gc_surface

from ..runtime.checks import LOOPBACK, check_editor, editor_out_dir
from ..runtime.config import sparse_settings
from .meshing import MeshLoop
from .session import POSE_AXES, EditorSession, Outcome

MESH_COLOR = (200, 170, 120)
GC_COLOR = (90, 160, 255)
POINT_COLOR = (255, 90, 60)
BLENDS = ("replace", "constant", "linear", "truncated_linear", "smoothstep")
STATUS_PREFIX = "mesh:"


OPS_SHOWN = 8  # the program's last ops listed in the panel (the rest counted): never cut off


def ops_text(ops: list[dict], shown: int = OPS_SHOWN) -> str:
    """The panel's program list: one line per op, the last `shown` of them, and how many
    came before (a long program stays within the panel instead of running off its bottom)."""
    if not ops:
        return "**program**: empty"
    first = max(0, len(ops) - shown)
    lines = [f"**program** ({len(ops)} op{'s' if len(ops) != 1 else ''})"]
    if first:
        lines.append(f"... {first} earlier")
    lines += [f"{i}. {o['op']} {o.get('gc')}" for i, o in enumerate(ops) if i >= first]
    return "  \n".join(lines)


def gc_middle(gc) -> np.ndarray:
    """(3,) a point at the middle of a GC's curve (where its label goes)."""
    pts = np.asarray(gc.curve.points, dtype=np.float64)
    return pts[len(pts) // 2] if len(pts) % 2 else 0.5 * (pts[len(pts) // 2 - 1]
                                                          + pts[len(pts) // 2])


def _guard(fn):
    """A GUI callback: skip programmatic updates (event.client None), report any exception in
    the message line instead of letting it reach viser."""
    @functools.wraps(fn)
    def wrapped(self, event=None):
        if event is not None and getattr(event, "client", True) is None:
            return
        try:
            fn(self, event)
        except Exception as e:  # the server never dies on a bad interaction
            self.say(f"internal error ({type(e).__name__}: {e})")
    return wrapped


def _plain(node) -> dict:
    """A config block (or dict, or None) as a plain dict of keyword arguments."""
    from omegaconf import OmegaConf

    if OmegaConf.is_config(node):
        return dict(OmegaConf.to_container(node, resolve=True))
    return dict(node or {})


class EditorServer:
    """session: what is edited; editor: the `editor` config block (host, port, resolutions,
    refine delay, out_dir); latent: a LatentShapes for a generation run, or None."""

    def __init__(self, session: EditorSession, editor, latent=None, out_dir: Path | None = None):
        import viser

        self.session, self.editor, self.latent = session, editor, latent
        self.out_dir = Path(out_dir) if out_dir is not None else editor_out_dir(editor)
        self.server = viser.ViserServer(host=str(editor.host), port=int(editor.port),
                                        verbose=False)
        self.server.initial_camera.position = tuple(float(x) for x in editor.camera)
        self.server.initial_camera.look_at = (0.0, 0.0, 0.0)
        env = editor.get("environment")
        self.server.scene.configure_environment_map(hdri=None if env is None else str(env))
        if env is None:  # no image-based light: an ambient light keeps the mesh readable
            self.server.scene.add_light_ambient("/ambient", intensity=1.5)
        self.shadows = bool(editor.get("shadows", False))
        self.server.scene.configure_default_lights(cast_shadow=self.shadows)
        self._lock = threading.RLock()
        self._handles: list = []
        self._drawn: dict = {}  # GC name -> (GC drawn, scene node)
        self._dragging = False
        self._build_gui()
        sparse = {} if editor.get("sparse") is None else {
            "settings": sparse_settings(editor.sparse)}
        self.loop = MeshLoop(session, editor.preview_resolution, editor.refine_resolution,
                             editor.refine_delay_s, self._show_mesh, self.say,
                             {**_plain(editor.get("preview_extract")), **sparse},
                             {**_plain(editor.get("refine_extract")), **sparse})
        self._draw_gcs()
        self._sync_controls()
        self.say(session.message)
        self.loop.start()

    @property
    def url(self) -> str:
        return f"http://{self.server.get_host()}:{self.server.get_port()}"

    def stop(self) -> None:
        self.loop.stop()
        self.server.stop()

    # ---- panel ----------------------------------------------------------------------------------
    def _build_gui(self) -> None:
        gui, s = self.server.gui, self.session
        self.status = gui.add_markdown(f"{STATUS_PREFIX} extracting ...")
        self.message = gui.add_markdown("")
        names = s.base.gc_names
        with gui.add_folder("Shape"):
            self.shape_menu = gui.add_dropdown("shape", tuple(s.library.names),
                                               initial_value=s.base.name)
            self.gc_menu = gui.add_dropdown("GC", tuple(names), initial_value=names[0])
        with gui.add_folder("Key (radius, twist)"):
            self.key_menu = gui.add_dropdown("key", ("0",), initial_value="0")
            self.radius = gui.add_slider("radius", min=0.0, max=0.5, step=0.001,
                                         initial_value=0.1)
            self.twist = gui.add_slider("twist (deg)", min=-360.0, max=360.0, step=1.0,
                                        initial_value=0.0)
        with gui.add_folder("Stretch"):
            self.stretch_t0 = gui.add_slider("from t", min=0.0, max=1.0, step=0.05,
                                             initial_value=0.0)
            self.stretch_t1 = gui.add_slider("to t", min=0.0, max=1.0, step=0.05,
                                             initial_value=1.0)
            self.stretch_factor = gui.add_slider("factor", min=0.5, max=2.0, step=0.01,
                                                 initial_value=1.0)
        with gui.add_folder("Pose (handles)"):
            self.pose_axis = gui.add_dropdown("axis", POSE_AXES, initial_value=POSE_AXES[0])
            self.pose_degrees = gui.add_slider("angle (deg)", min=-120.0, max=120.0, step=1.0,
                                               initial_value=0.0)
        with gui.add_folder("Mix parts", expand_by_default=False):
            self.mix_shape = gui.add_dropdown("source shape", tuple(s.library.names),
                                              initial_value=s.library.names[0])
            self.mix_gc = gui.add_dropdown("source GC", tuple(names), initial_value=names[0])
            self.mix_blend = gui.add_dropdown("blend", BLENDS, initial_value="replace")
            self.mix_t0 = gui.add_slider("blend t0", min=0.0, max=1.0, step=0.05,
                                         initial_value=0.3)
            self.mix_t1 = gui.add_slider("blend t1", min=0.0, max=1.0, step=0.05,
                                         initial_value=0.7)
            self.mix_w = gui.add_slider("blend w", min=0.0, max=1.0, step=0.05,
                                        initial_value=0.5)
            self.mix_geometry = gui.add_dropdown("geometry", ("source", "target"),
                                                 initial_value="source")
            self.mix_button = gui.add_button("mix into selected GC")
        if self.latent is not None:
            with gui.add_folder("Generate"):
                self.seed = gui.add_number("seed", initial_value=int(self.editor.seed), step=1)
                self.sample_button = gui.add_button("sample", disabled=not self.latent.can_sample)
                names_a = self.latent.generator.names
                self.lerp_a = gui.add_text("A", initial_value=names_a[0])
                self.lerp_b = gui.add_text("B", initial_value=names_a[min(1, len(names_a) - 1)])
                self.lerp_alpha = gui.add_slider("A <-> B", min=0.0, max=1.0, step=0.05,
                                                 initial_value=0.0)
                self.sample_button.on_click(self._on_sample)
                self.lerp_alpha.on_update(self._on_lerp)
        with gui.add_folder("Program"):
            self.undo_button = gui.add_button("undo")
            self.redo_button = gui.add_button("redo")
            self.save_button = gui.add_button("save program")
            self.export_button = gui.add_button("export mesh")
            self.export_glb_button = gui.add_button("export glb")
            self.ops_view = gui.add_markdown("")

        self.shape_menu.on_update(self._on_shape)
        self.gc_menu.on_update(self._on_selection)
        self.key_menu.on_update(self._on_key)
        self.radius.on_update(self._on_radius)
        self.twist.on_update(self._on_twist)
        self.stretch_factor.on_update(self._on_stretch)  # t0, t1 only say where
        for c in (self.stretch_t0, self.stretch_t1, self.pose_axis):
            c.on_update(self._on_selection)  # a new range or axis: its controls start at no change
        self.pose_degrees.on_update(self._on_pose)
        self.mix_shape.on_update(self._on_mix_shape)
        self.mix_button.on_click(self._on_mix)
        self.undo_button.on_click(self._on_undo)
        self.redo_button.on_click(self._on_redo)
        self.save_button.on_click(self._on_save)
        self.export_button.on_click(self._on_export)
        self.export_glb_button.on_click(self._on_export_glb)

    def say(self, text: str) -> None:
        self.message.content = text

    # ---- scene ----------------------------------------------------------------------------------
    def _show_mesh(self, version: int, resolution: int, result, seconds: float) -> None:
        mesh = result.mesh
        if len(mesh.faces):
            self.server.scene.add_mesh_simple("/shape", mesh.vertices, mesh.faces,
                                              color=MESH_COLOR, side="double",
                                              cast_shadow=self.shadows,
                                              receive_shadow=self.shadows)
        self.status.content = (f"{STATUS_PREFIX} version {version}, {resolution}^3, "
                               f"{len(mesh.faces)} faces, {seconds:.2f} s")

    def _draw_gcs(self) -> None:
        """GC overlay: one translucent node per GC, redrawn only for GC objects that changed
        (GCs no op touches stay the same objects), and all control points as dots."""
        shape = self.session.snapshot()[1]
        drawn = self._drawn
        for name in set(drawn) - set(shape.gc_names):
            for node in drawn.pop(name)[1:]:
                node.remove()
        for g in shape.gcs:
            if g.name in drawn and drawn[g.name][0] is g:
                continue
            surf = gc_surface(g, n_u=32, n_theta=16)
            node = self.server.scene.add_mesh_simple(
                f"/gcs/{g.name}", surf.vertices, surf.faces, color=GC_COLOR, opacity=0.2,
                side="front", cast_shadow=False, receive_shadow=False)  # a translucent shell:
            # its near side is enough, and one pass instead of two (software WebGL in headless
            # Chromium, idle machine: preview drawn 0.41-0.70 s vs 0.60-0.79 s double-sided)
            node.on_click(functools.partial(self._on_pick, g.name))  # click a GC: select it
            label = self.server.scene.add_label(  # its name in the view, at its middle
                f"/labels/{g.name}", g.name, position=tuple(float(x) for x in gc_middle(g)),
                anchor="bottom-center", font_screen_scale=0.8)
            drawn[g.name] = (g, node, label)
        pts = np.concatenate([g.curve.points for g in shape.gcs]).astype(np.float32)
        self.server.scene.add_point_cloud("/points", pts, colors=POINT_COLOR, point_size=0.012,
                                          point_shape="circle")

    def _gc(self):
        shape = self.session.snapshot()[1]
        return shape.gcs[shape.index(self.gc_menu.value)]

    def _place_handles(self) -> None:
        """Transform controls on the selected GC's control points (rebuilt when the GC or its
        number of points changes, moved otherwise)."""
        pts = self._gc().curve.points
        name = self.gc_menu.value
        if len(self._handles) != len(pts) or getattr(self, "_handles_gc", None) != name:
            for h in self._handles:
                h.remove()
            self._handles = []
            for j, p in enumerate(pts):
                h = self.server.scene.add_transform_controls(
                    f"/control/{j}", scale=0.12, disable_rotations=True, depth_test=False,
                    position=tuple(float(x) for x in p))
                h.on_update(functools.partial(self._on_drag, j))
                self._handles.append(h)
            self._handles_gc = name
        else:
            for h, p in zip(self._handles, pts):
                h.position = tuple(float(x) for x in p)

    # ---- keeping controls in step with the session ----------------------------------------------
    def _sync_controls(self) -> None:
        """Set every control from the session's state (after any interaction, accepted or
        refused), without triggering interactions (programmatic updates are skipped)."""
        with self._lock:
            shape = self.session.snapshot()[1]
            if self.gc_menu.value not in shape.gc_names:
                self.gc_menu.options = tuple(shape.gc_names)
            gc = self._gc()
            keys = tuple(f"{i}: t={k.t:.2f}" for i, k in enumerate(gc.keys))
            if tuple(self.key_menu.options) != keys:
                self.key_menu.options = keys
            # another GC: its first key, never the previous GC's key index carried over
            if self.key_menu.value not in keys or getattr(self, "_keys_gc", None) != gc.name:
                self.key_menu.value = keys[0]
            self._keys_gc = gc.name
            k = gc.keys[self._key_index()]
            self.radius.value = round(0.5 * (k.radii[0] + k.radii[1]), 3)
            self.twist.value = float(np.clip(round(k.twist), -360, 360))
            if not self._dragging:
                self._place_handles()
            # relative controls start at "no change" unless the next move updates the last op
            name = self.gc_menu.value
            if not self.session.continues(("stretch", name, float(self.stretch_t0.value),
                                           float(self.stretch_t1.value))):
                self.stretch_factor.value = 1.0
            if not self.session.continues(("pose", name, str(self.pose_axis.value))):
                self.pose_degrees.value = 0.0
            self.ops_view.content = ops_text(self.session.ops)
            self.undo_button.disabled = not self.session.can_undo
            self.redo_button.disabled = not self.session.can_redo

    def _key_index(self) -> int:
        return int(str(self.key_menu.value).split(":")[0])

    def select(self, gc: str) -> None:
        """Select a GC (its keys in the sliders, its control points as handles)."""
        self.gc_menu.value = gc
        self._sync_controls()

    def shown_mesh(self):
        """The ExtractionResult of the current document as the scene shows it once refined
        (the session's cached result, or extracted now)."""
        return self.session.mesh(self.loop.refine, **self.loop.extract_kw[self.loop.refine])

    def apply(self, out: Outcome, released: bool = False, sync: bool = True) -> Outcome:
        """After a session interaction (what every callback does): message, GC overlay,
        controls, and a new mesh if it was accepted (refined at once if `released`)."""
        self.say(out.message)
        if out.ok:
            self.loop.changed(released=released)
            self._draw_gcs()
        if sync:
            self._sync_controls()
        return out

    # ---- callbacks ------------------------------------------------------------------------------
    @_guard
    def _on_shape(self, _):
        self.apply(self.session.open(self.shape_menu.value), released=True)

    @_guard
    def _on_selection(self, _):
        self._sync_controls()

    def _on_pick(self, name: str, event=None):
        """A click on a GC in the 3D view selects it (as the GC menu does)."""
        try:
            if name in self.session.snapshot()[1].gc_names:
                self.select(name)
                self.say(f"selected GC '{name}'")
        except Exception as e:  # the server never dies on a bad interaction
            self.say(f"internal error ({type(e).__name__}: {e})")

    @_guard
    def _on_key(self, _):
        self._sync_controls()

    @_guard
    def _on_radius(self, _):
        self.apply(self.session.set_radius(self.gc_menu.value, self._key_index(),
                                           float(self.radius.value)))

    @_guard
    def _on_twist(self, _):
        self.apply(self.session.set_twist(self.gc_menu.value, self._key_index(),
                                          float(self.twist.value)))

    @_guard
    def _on_stretch(self, _):
        self.apply(self.session.stretch(self.gc_menu.value, float(self.stretch_t0.value),
                                        float(self.stretch_t1.value),
                                        float(self.stretch_factor.value)))


    @_guard
    def _on_pose(self, _):
        self.apply(self.session.pose(self.gc_menu.value, str(self.pose_axis.value),
                                     float(self.pose_degrees.value)))

    @_guard
    def _on_mix_shape(self, _):
        src = self.session.library[self.mix_shape.value]
        self.mix_gc.options = tuple(src.gc_names)

    @_guard
    def _on_mix(self, _):
        blend = str(self.mix_blend.value)
        params = {"t0": float(self.mix_t0.value), "t1": float(self.mix_t1.value)} \
            if blend in ("truncated_linear", "smoothstep") else \
            ({"w": float(self.mix_w.value)} if blend == "constant" else {})
        self.apply(self.session.mix(self.gc_menu.value, str(self.mix_shape.value),
                                    str(self.mix_gc.value), blend,
                                    str(self.mix_geometry.value), **params), released=True)

    def _on_drag(self, index: int, event) -> None:
        if event.client is None:
            return
        try:
            self._dragging = event.phase != "end"
            out = self.session.move_point(self.gc_menu.value, index,
                                          np.asarray(event.target.position, dtype=np.float64))
            self.apply(out, released=event.phase == "end", sync=event.phase == "end")
            if event.phase == "end" and not out.ok:
                self._sync_controls()
        except Exception as e:
            self._dragging = False
            self.say(f"internal error ({type(e).__name__}: {e})")

    @_guard
    def _on_undo(self, _):
        self.apply(self.session.undo(), released=True)

    @_guard
    def _on_redo(self, _):
        self.apply(self.session.redo(), released=True)

    @_guard
    def _on_save(self, _):
        self.say(self.session.save(self.out_dir / workspace.PROGRAM,
                                   int(self.editor.refine_resolution)).message)

    @_guard
    def _on_export(self, _):
        self.say(self.session.export_mesh(self.out_dir / "mesh.ply",
                                          int(self.editor.refine_resolution)).message)

    @_guard
    def _on_export_glb(self, _):
        from ..stages.export_shape import default_parents

        self.say(self.session.export_glb(self.out_dir / "shape.glb",
                                         int(self.editor.refine_resolution),
                                         default_parents(self.session.shape.gc_names)).message)

    @_guard
    def _on_sample(self, _):
        shape = self.latent.sample(int(self.seed.value))
        self._opened(shape.name)

    @_guard
    def _on_lerp(self, _):
        shape = self.latent.interpolate(str(self.lerp_a.value), str(self.lerp_b.value),
                                        float(self.lerp_alpha.value), int(self.seed.value))
        self._opened(shape.name, released=False)

    def _opened(self, name: str, released: bool = True) -> None:
        names = tuple(self.session.library.names)
        self.shape_menu.options = names
        self.mix_shape.options = names
        self.shape_menu.value = name
        self.apply(self.session.open(name), released=released)


def serve(cfg) -> dict:
    """`edit.py viewer=true`: open the session, start the server, run until Ctrl-C."""
    from .start import open_session

    check_editor(cfg)  # again for callers other than edit.py; cheap
    session, latent = open_session(cfg)
    editor = cfg.editor
    server = EditorServer(session, editor, latent,
                          out_dir=editor.out_dir if editor.get("out_dir") else None)
    print(f"editor on {server.url} (shape '{session.base.name}'); saves go to "
          f"{server.out_dir.resolve()}; Ctrl-C stops it")
    if str(editor.host) not in LOOPBACK:
        print(f"warning: the editor listens on {editor.host} (editor.allow_remote=true): anyone "
              f"who can reach this machine can edit and write files through it")
    else:
        print(f"remote machine? ssh -L {server.server.get_port()}:127.0.0.1:"
              f"{server.server.get_port()} <host>, then open {server.url} locally")
    try:
        while True:
            time.sleep(1.0)
    except KeyboardInterrupt:
        pass
    finally:
        server.stop()
    return {"url": server.url, "ops": session.ops}
