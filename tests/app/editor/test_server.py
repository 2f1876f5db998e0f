"""The viser server without a browser: callbacks turn GUI values into session interactions, a
refused or failing interaction springs the controls back and leaves a message, and the server
keeps serving; edit.py's `viewer=true` reaches the editor."""
from types import SimpleNamespace

import numpy as np
import pytest

from ngc_gen.app.runtime.errors import ConfigError

from tests.app.editor import browser
from ngc_gen.app.editor.server import OPS_SHOWN, EditorServer, gc_middle, ops_text
from ngc_gen.data.errors import DataError
from ngc_gen.app.stages.edit_shapes import run_edit

from ...helpers import compose_config
from .conftest import editor_config

pytestmark = pytest.mark.usefixtures("single_thread")
USER = object()  # a client: events from the page carry one, programmatic updates None


@pytest.fixture
def server(session, checkpoint, tmp_path):
    cfg = editor_config(checkpoint, f"editor.port={browser.free_port()}",
                        "editor.preview_resolution=16", "editor.refine_resolution=24")
    srv = EditorServer(session, cfg.editor, None, out_dir=tmp_path)
    yield srv
    srv.stop()


def user_sets(control, value):
    """What viser does when the page changes a control: set it, then run its callbacks with
    the client's event."""
    control._impl.value = value
    for cb in control._impl.update_cb:
        cb(SimpleNamespace(client=USER, target=control))


def test_sliders_edit_and_bad_values_spring_back(server):
    s = server.session
    server.select("arm")
    user_sets(server.twist, 30.0)
    assert s.ops == [{"op": "twist", "gc": "arm", "t": 0.0, "degrees": 30.0}]
    assert server.message.content.startswith("added ops[0]")
    radius = server.radius.value
    user_sets(server.radius, 0.0)
    assert server.message.content.startswith("refused: ") and len(s.ops) == 1
    assert server.radius.value == radius  # the slider shows the last valid radius again
    assert server.loop.wait_for(s.version, 24, timeout=60).n_faces > 100


def test_a_failing_interaction_is_reported_and_the_server_goes_on(server, monkeypatch):
    def boom(*a, **k):
        raise RuntimeError("boom")

    monkeypatch.setattr(server.session, "set_twist", boom)
    user_sets(server.twist, 10.0)
    assert server.message.content == "internal error (RuntimeError: boom)"
    monkeypatch.undo()
    user_sets(server.twist, 10.0)
    assert server.session.ops[-1]["degrees"] == 10.0


def test_dragging_a_control_point(server):
    s = server.session
    server.select("tail")
    handle = server._handles[1]
    start = s.shape.gcs[2].curve.points[1].copy()

    def drag(position, phase):
        handle._impl.position = np.asarray(position, dtype=np.float64)
        server._on_drag(1, SimpleNamespace(client=USER, target=handle, phase=phase))

    for k in (1, 2, 3):
        drag(start + [0.0, 0.0, 0.02 * k], "update")
    drag(start + [0.0, 0.0, 0.06], "end")
    assert len(s.ops) == 1 and s.ops[0]["op"] == "move"
    np.testing.assert_allclose(s.shape.gcs[2].curve.points[1], start + [0, 0, 0.06], atol=1e-12)
    # onto its neighbour: refused, and the handle goes back to the point on release
    drag(s.shape.gcs[2].curve.points[0] + 1e-4, "update")
    drag(s.shape.gcs[2].curve.points[0] + 1e-4, "end")
    assert server.message.content.startswith("refused: ")
    np.testing.assert_allclose(handle.position, start + [0, 0, 0.06], atol=1e-6)


def test_edit_py_viewer_true_opens_the_editor():
    with pytest.raises(ConfigError, match="no run given.*editor.generator"):
        run_edit(compose_config("edit", ["viewer=true"]))


def test_relative_sliders_restart_at_no_change(server):
    s = server.session
    server.select("body")
    user_sets(server.stretch_factor, 1.2)
    user_sets(server.stretch_factor, 1.1)  # the same stretch, updated
    assert [o["op"] for o in s.ops] == ["stretch"] and s.ops[0]["factor"] == 1.1
    user_sets(server.twist, 15.0)
    assert server.stretch_factor.value == 1.0  # another op came between: a new stretch
    user_sets(server.stretch_factor, 1.05)
    assert [o["op"] for o in s.ops] == ["stretch", "twist", "stretch"]
    user_sets(server.pose_degrees, 20.0)
    user_sets(server.pose_axis, "binormal")
    assert server.pose_degrees.value == 0.0 and len(s.ops) == 4


def test_another_gc_starts_at_its_first_key(server):
    server.select("body")
    user_sets(server.key_menu, server.key_menu.options[-1])   # body's key at t=1
    assert server._key_index() == 1
    server.select("arm")                                      # arm also has keys 0 and 1
    assert server._key_index() == 0
    user_sets(server.twist, 25.0)
    op = server.session.ops[-1]
    assert (op["op"], op["gc"], op["t"]) == ("twist", "arm", 0.0)  # not arm's t=1 unasked


def test_gcs_are_labelled_in_the_view_and_picked_by_a_click(server):
    for name in server.session.shape.gc_names:
        g, node, label = server._drawn[name]
        assert label.text == name
        assert np.allclose(label.position, gc_middle(g))
        clicks = node._impl.click_cb
        assert len(clicks) == 1
        clicks[0].callback(SimpleNamespace(client=USER, target=node))
        assert server.gc_menu.value == name and server._handles_gc == name


def test_a_long_program_stays_within_the_panel():
    ops = [{"op": "twist", "gc": f"g{i}"} for i in range(30)]
    text = ops_text(ops)
    lines = text.split("  \n")
    assert len(lines) == 2 + OPS_SHOWN and "... 22 earlier" in lines[1]
    assert lines[-1] == "29. twist g29" and "(30 ops)" in lines[0]
    assert ops_text([]) == "**program**: empty"


def test_the_shape_casts_no_shadow_by_default(server):
    """Shadow maps cost a pass per frame: in headless Chromium's software GL they made the
    preview appear 1.5-1.7 s after an input instead of 0.85-0.97 s (measured at load 4)."""
    import trimesh

    assert server.shadows is False
    server._show_mesh(99, 16, SimpleNamespace(mesh=trimesh.creation.box()), 0.01)
    props = server.server.scene._handle_from_node_name["/shape"]._impl.props
    assert props.cast_shadow is False and props.receive_shadow is False


def test_export_glb_button_writes_the_current_shape(server, tmp_path):
    """The panel's export glb button writes shape.glb: the current (edited) shape's mesh with
    its GC chains as the skeleton, as sample.py mode=export writes it."""
    from ngc_gen.export import Playback
    from ngc_gen.export.validator import validate, validator_available

    s = server.session
    server.select("arm")
    user_sets(server.twist, 30.0)
    for cb in server.export_glb_button._impl.update_cb:  # what a click on the page runs
        cb(SimpleNamespace(client=USER, target=server.export_glb_button))
    out = tmp_path / "shape.glb"
    assert server.message.content.startswith("exported ") and out.is_file(), \
        server.message.content
    p = Playback(out)
    assert p.joint_names[:2] == ["body_0", "body_1"] and len(p.joint_names) == 3 * 4
    mesh = s.mesh(24).mesh  # the editor's refine resolution: the mesh it shows, edited
    assert np.allclose(p.vertices(), mesh.vertices, atol=1e-6)
    if validator_available():
        assert validate(out)["errors"] == 0
