"""The body frame a collection was written in travels with what is made from it: the
shape-latent run's meta, generated shapes' YAMLs, shapes.ckpt (edit.py), and every picture
stands on it without `viz.up`."""
import numpy as np
import pytest
import torch
import trimesh

from ngc_gen.app.stages.train_shape_latent import check_layouts
from ngc_gen.data.annotations import Annotation, load_annotation
from ngc_gen.data.body_frame import body_axes, collection_frame, read_frame
from ngc_gen.data.errors import DataError
from ngc_gen.generate.shapes import write_edit_checkpoint, write_shape
from ngc_gen.geometry import GeneralizedCylinder
from ngc_gen.models import NGCDecoder
from ngc_gen.shape import load_shapes
from ngc_gen.viz.camera import frame_up, resolve_up

Y_UP = {"up": [0, 1, 0], "front": [0, 0, 1]}


def annotation(name, gc_dict, frame=None):
    return Annotation(name, "x.ply", [GeneralizedCylinder.from_dict(gc_dict("torso", -0.3, 0.3))],
                      frame=read_frame(frame))


def test_a_collection_has_one_frame_or_is_refused(gc_dict):
    anns = [annotation(n, gc_dict, Y_UP) for n in ("cow", "camel")]
    assert check_layouts(anns) == {"up": [0.0, 1.0, 0.0], "front": [0.0, 0.0, 1.0]}
    assert check_layouts([annotation("cow", gc_dict)]) is None
    turned = annotation("bull", gc_dict, {"up": [0, 0, 1], "front": [1, 0, 0]})
    with pytest.raises(DataError, match="bull.*cow.*one body frame"):
        check_layouts(anns + [turned])
    with pytest.raises(DataError, match="1 of 3 shapes record no body frame"):
        check_layouts(anns + [annotation("pig", gc_dict)])
    axes = body_axes(read_frame(Y_UP))
    assert np.allclose(axes["left"], [1, 0, 0])  # y up, facing +z: the left side is +x


def test_a_bad_frame_names_the_field(write_yaml, sphere_file, gc_dict):
    d = {"name": "s", "mesh": sphere_file.name, "gcs": [gc_dict("body", -0.3, 0.3)]}
    assert load_annotation(write_yaml({**d, "frame": Y_UP})).frame["up"] == [0.0, 1.0, 0.0]
    with pytest.raises(DataError, match="frame.up"):
        load_annotation(write_yaml({**d, "frame": {"up": [0, 0, 0], "front": [1, 0, 0]}}))
    with pytest.raises(DataError, match="not perpendicular"):
        load_annotation(write_yaml({**d, "frame": {"up": [0, 1, 0], "front": [0, 1, 1]}}))


def test_generated_shapes_carry_the_frame_to_edits_and_pictures(tmp_path, gc_dict):
    """A generated shape's YAML and shapes.ckpt record the model's frame; edit.py's shapes
    read it back; a picture with viz.up=auto stands on it, not on a detected axis."""
    mesh = trimesh.creation.box(extents=(1.6, 0.3, 0.6))  # flat along y: detection says +y...
    mesh.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
    assert not np.allclose(resolve_up("auto", [mesh]), [0, 1, 0])  # ...turned, it says z
    gc = gc_dict("torso", -0.3, 0.3)
    written = write_shape(tmp_path, "sample_000", mesh, [gc], torch.zeros(1, 8), body=Y_UP)
    assert load_annotation(written.annotation).frame["up"] == [0.0, 1.0, 0.0]
    ngc = NGCDecoder(8, 8, 8, 1, 8, 1, 1)
    write_edit_checkpoint(tmp_path / "shapes.ckpt", ngc, [written])
    shape = load_shapes(tmp_path / "shapes.ckpt")["sample_000"]
    assert shape.info["frame"]["up"] == [0.0, 1.0, 0.0]
    up = frame_up("auto", shape.info["frame"])
    assert np.allclose(resolve_up(up, [mesh]), [0, 1, 0])
    assert frame_up("z", shape.info["frame"]) == "z"  # a given viz.up wins
    assert frame_up("auto", None) == "auto"


def test_the_animals_record_their_frame():
    from ngc_gen.app.runtime.config import compose_config
    from hydra.utils import instantiate

    data = instantiate(compose_config("train", ["data=animals", "run_dir=x"]).data)
    assert data.frame["up"] == [0.0, 1.0, 0.0] and data.frame["front"] == [0.0, 0.0, 1.0]
    assert collection_frame([("a", data.frame)]) == {"up": [0.0, 1.0, 0.0],
                                                     "front": [0.0, 0.0, 1.0]}
