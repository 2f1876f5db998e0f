"""The template's checks that tell a right frame from a wrong one that fits as cheaply: a body
stood on end (front and up swapped: a tall, long-necked animal's neck read as its back) fails
`spine` (an elephant's torso climbing into its neck passes by its level back), a thick head or
tail taken for a leg (a gallop read back to front) fails `legs`, ears or a tail running sideways
(a body laid on its side) fail `downward`, ears hanging as hind legs (a body upside down) fail
`weight`, and a path down one leg and up the other, named for the wrong leg, fails `sides`.
Paths in body coordinates, as ``verify`` reads a match."""
from __future__ import annotations

import numpy as np
import pytest

from ngc_gen.data.autogc.template import load_template
from ngc_gen.data.autogc.transfer.verify import verify

from ...helpers import ROOT

TEMPLATE = ROOT / "datasets/animals/quadruped_transfer.yaml"


@pytest.fixture(scope="module")
def template():
    return load_template(TEMPLATE)


def _paths(parts: dict) -> tuple[dict, np.ndarray]:
    """{name: (start, end)} -> ({name: node indices}, nodes (N, 3)), 5 nodes a part."""
    nodes, paths = [], {}
    for name, (a, b) in parts.items():
        paths[name] = np.arange(len(nodes), len(nodes) + 5)
        nodes.extend(np.linspace(a, b, 5))
    return paths, np.asarray(nodes, dtype=float)


def _surface(template, held: dict) -> np.ndarray:
    return np.array([held.get(n, 0.0) for n in template.names])


UPRIGHT = {"torso": ((-0.6, 0, 0.2), (0.2, 0, 0.1)), "neck": ((0.3, 0, 0.2), (0.6, 0, 0.6)),
           "head": ((0.6, 0, 0.6), (0.9, 0, 0.5)), "tail": ((-0.6, 0, 0.2), (-0.9, 0, 0.0)),
           **{n: ((f, s, 0.0), (f, s, -0.9)) for n, f, s in
              (("leg_fl", 0.3, 0.5), ("leg_fr", 0.3, -0.5), ("leg_bl", -0.6, 0.5),
               ("leg_br", -0.6, -0.5))}}
HELD = {"torso": 0.4, "neck": 0.12, "head": 0.08, "tail": 0.04, "leg_fl": 0.09, "leg_fr": 0.09,
        "leg_bl": 0.09, "leg_br": 0.09}


def test_a_body_stood_on_end_fails_the_spine_check(template):
    """A long-necked walking animal (an alpaca) turned about the line between its back and its
    neck: its neck runs forward, its back stands upright, the hind feet point backwards and a
    front leg is read as the tail. Head and tail lie at opposite ends, the feet below the torso,
    the sides right, neck and head hold more surface than the tail: only the torso's direction
    (50 degrees off the template's in this frame's lengths) tells it."""
    half = np.array([0.76, 0.2, 0.83])
    on_end = {"torso": ((-0.27, -0.13, 0.11), (0.12, 0.01, -0.5)),
              "neck": ((0.0, 0.0, 0.22), (0.77, -0.1, 0.76)),
              "head": ((0.77, -0.1, 0.76), (0.89, 0.12, 0.77)),
              "tail": ((-0.27, -0.13, 0.11), (-0.9, -0.49, 0.14)),
              "leg_fl": ((-0.23, 0.04, 0.06), (-0.74, 0.48, -0.23)),
              "leg_bl": ((0.11, 0.11, -0.52), (-0.39, 0.45, -0.79)),
              "leg_br": ((0.11, -0.17, -0.54), (-0.46, -0.6, -0.95))}
    held = {"torso": 0.24, "neck": 0.26, "head": 0.05, "tail": 0.1, "leg_fl": 0.1,
            "leg_bl": 0.11, "leg_br": 0.14}
    paths, nodes = _paths(on_end)
    radius = np.full(len(nodes), 0.03)
    surface = _surface(template, held)
    failed = verify(template, paths, nodes, surface, half, radius, spine=True).failed
    assert failed is not None and failed.startswith("spine: the torso runs"), failed
    # given axes or a frame levelled on its feet are not asked: every other check passes
    assert verify(template, paths, nodes, surface, half, radius).ok
    paths, nodes = _paths(UPRIGHT)  # the upright animal passes, in the same box
    assert verify(template, paths, nodes, _surface(template, HELD), half,
                  np.full(len(nodes), 0.03), spine=True).ok


def test_a_head_taken_for_a_leg_fails_the_legs_check(template):
    """A galloping deer read back to front: its hind legs as front legs, its rump as the neck,
    a hind foot as the head, and the head, three times as thick as a shin, as a hind leg. The
    ends, the ground and the weight pass; the legs are not alike."""
    paths, nodes = _paths(UPRIGHT)
    surface = _surface(template, HELD)
    radius = np.full(len(nodes), 0.025)
    assert verify(template, paths, nodes, surface, None, radius).ok
    radius[paths["leg_br"]] = 0.08
    failed = verify(template, paths, nodes, surface, None, radius).failed
    assert failed is not None and failed.startswith("legs: leg_br is 3.2x as thick as"), failed
    radius[paths["leg_br"][:2]] = 0.025   # a thick thigh over a thin shin is a leg: the outer
    radius[paths["leg_br"][2:]] = 0.04    # half is what is compared, within 2.5x
    assert verify(template, paths, nodes, surface, None, radius).ok


def test_a_torso_climbing_into_the_neck_passes_the_spine_check_by_its_back(template):
    """An elephant's torso path runs from its rump up into the neck's base, 40+ degrees off the
    template's torso in the right frame; the back between where its hind and its front legs
    join runs level, as the template's does, and the frame passes."""
    half = np.array([0.8, 0.3, 0.7])
    climbing = {**UPRIGHT, "torso": ((-0.6, 0, 0.0), (0.3, 0, 0.7))}
    paths, nodes = _paths(climbing)
    surface, radius = _surface(template, HELD), np.full(len(nodes), 0.03)
    assert verify(template, paths, nodes, surface, half, radius, spine=True).ok
    del climbing["leg_fl"], climbing["leg_fr"]  # no front legs: only the torso's path to go by
    paths, nodes = _paths(climbing)
    failed = verify(template, paths, nodes, surface, half, np.full(len(nodes), 0.03),
                    spine=True).failed
    assert failed is not None and failed.startswith("spine: the torso runs 45 degrees"), failed


def test_a_leg_path_across_the_middle_fails_the_sides_check(template):
    """Two hind legs joined at the feet: the path taken for the left one runs down the right
    leg, across and up the left one to a stub; its partner is missing, so only the path's own
    side tells it."""
    parts = {k: v for k, v in UPRIGHT.items() if k not in ("leg_bl", "leg_br")}
    paths, nodes = _paths(parts)
    across = np.array([(-0.6, -0.1, 0.1), (-0.6, -0.5, -0.3), (-0.6, -0.5, -0.6),
                       (-0.6, -0.5, -0.9), (-0.6, -0.1, -0.9), (-0.6, 0.3, -0.6)])
    paths["leg_bl"] = np.arange(len(nodes), len(nodes) + len(across))
    nodes = np.concatenate([nodes, across])
    failed = verify(template, paths, nodes, _surface(template, HELD), None,
                    np.full(len(nodes), 0.03)).failed
    assert failed is not None and failed.startswith("sides: leg_bl lies right of the torso"), failed
    nodes[paths["leg_bl"], 1] *= 0.5  # on the middle (a leg under the body): passes
    assert verify(template, paths, nodes, _surface(template, HELD), None,
                  np.full(len(nodes), 0.03)).ok


def test_legs_running_sideways_fail_the_downward_check(template):
    """A body laid on its side: the ears, the tail and a neck read as legs run sideways out of
    the torso, dipping below it; every other check passes."""
    lying = {**UPRIGHT, **{n: ((f, 0.1 * np.sign(s), 0.0), (f, s, -0.3)) for n, f, s in
                           (("leg_fl", 0.3, 0.9), ("leg_fr", 0.3, -0.9), ("leg_bl", -0.6, 0.9),
                            ("leg_br", -0.6, -0.9))}}
    paths, nodes = _paths(lying)
    failed = verify(template, paths, nodes, _surface(template, HELD), None,
                    np.full(len(nodes), 0.03)).failed
    assert failed is not None and failed.startswith("downward: the legs run 69 degrees"), failed


def test_an_ear_read_as_a_leg_fails_the_weight_check(template):
    """A body upside down: its ears, thin and short, hang below the torso as its hind legs. They
    hold a tenth of a leg's share of the surface."""
    paths, nodes = _paths(UPRIGHT)
    radius = np.full(len(nodes), 0.03)
    held = {**HELD, "leg_bl": 0.006, "leg_br": 0.006}
    failed = verify(template, paths, nodes, _surface(template, held), None, radius).failed
    assert failed is not None and failed.startswith("weight: leg_bl holds 0.6% of the surface"), \
        failed
    assert verify(template, paths, nodes, _surface(template, HELD), None, radius).ok
