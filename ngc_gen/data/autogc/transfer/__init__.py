"""Template transfer: one named GC template on a mesh without a rig (docs/transfer.md).

Pinocchio's two steps (a discrete embedding, then a continuous refinement) on our skeleton:
1. Orientation (``orientation``): the mesh's up and front, found in any rotation and checked
   (``verify``); every position below
   is read in the body frame (front, left, up) of the surface's bounding box, divided by its
   half extents, as the template's `place` is.
2. Skeleton tree: closed proxy -> curve skeleton -> branch graph (``skeleton_gcs``' steps), as
   one graph of nodes; its largest piece is the body.
3. Correspondence: the template's leaf GCs (no children) onto the tree's leaves by one optimal
   assignment (Hungarian) with geometric costs: where the tip lies (side included, so a left
   leg cannot take a right foot; half as strict across for a part on the mid-plane), where
   its branch leaves the body (front to back, capped), the direction toward it from its
   branch's root, and its thickness relative to the body's thickest part against the
   template's; any template leaf
   may stay unmatched at ``missing_cost``. Two limbs of one side whose branches leave the body
   in the other order than the template starts them (a gallop's crossed legs) are swapped
   (``_front_to_back``); once the paths are known, the legs are named front or hind by
   where their paths leave the body (``_legs_by_start``). A second pass gives the limbs left out (a grazing
   head, galloping legs) the free ends left over that lie within their reach: at the limb
   chain's length from where it attaches, on its own side (a mid-plane part's branch not much
   shorter than its template part: a spur in the hip is no tail); a paired limb whose end lies
   across the mid-plane is left out, and a tail whose end lies off it (a spur in one hip).
   Still missing: matched once more
   on a finer tree (spurs ``FINER`` x as long kept: a short tail). Tree-consistent by
   construction: a leaf's path toward the template root's place is its own up to where it
   meets another matched leaf's path (its junction); a chain
   of template GCs above one leaf (neck, head) shares that path by the template's lengths (up
   to where the template's chain ends, when the path runs on past it: a trunk); a
   GC above several matched leaves (a torso) is the longest tree path between its children's
   junctions. Every other skeleton node (ears, antlers) goes to the GC nearest along the tree.
   Too few matched leaves, or a mean cost of the matched ones above ``max_match_cost``: the
   mesh does not match.
4. GCs: each surface sample belongs to its nearest skeleton node's GC, or a leg's when it is
   the leg's parent's flank up to the leg's joint (``roots``); a GC is the template's
   degree of Bezier through its path (free ends extended to the surface), radii and caps from
   its own samples (``rig_gcs.template_gc``, as for a rig), the template's `up` turned into the
   mesh's frame. A template part the mesh lacks is its found symmetric partner's mirror
   image where that lies on the surface (``mirror``), else it reaches from its attachment to
   the surface nearest where its tip would be (a pruned stub), else it is a small GC at its
   attachment.
5. Refinement (torch, all GCs at once): control points and per-key radii so each GC's own
   samples lie at its radius from its curve (the union's boundary near the surface, the
   surface inside), children start inside their parents, curves stay smooth and symmetric
   pairs keep one thickness profile (their positions mirror only weakly: a posed animal's legs
   are not mirror images); then radii and caps are refitted to
   the refined curves and the GCs cover the surface hugging it (``hug``, settings `hug`,
   `hug_quantile`: radii from each part's own slices, the rest by the cheapest local growth,
   then tightened and each curve centred on what its GC holds), or with `hug` off as for a
   rig (``coverage.grow_to_cover``).

Modules: transfer_settings (TransferSettings, Transfer), tree (body frame, skeleton tree),
orientation (which way the mesh faces), match (correspondence, paths), leg_order (legs
named front or hind by where they leave the body), verify (the template's
checks), roots (a leg's surface up to its joint), mirror (a missing part of a pair), refine
(torch refinement), assemble (the whole transfer), export (templates from annotated meshes).
"""
from .assemble import START_REACH, _moved_ends, _reach_back, transfer_template
from .export import _attachment, _inferred_tree, export_template
from .match import _front_to_back, correspond, match_cost
from .transfer_settings import Transfer, TransferSettings
from .tree import BodyFrame, Tree, skeleton_tree, template_rotation

__all__ = ["BodyFrame", "START_REACH", "Transfer", "TransferSettings", "Tree", "_attachment",
           "_front_to_back", "_inferred_tree", "_moved_ends", "_reach_back", "correspond",
           "export_template", "match_cost", "skeleton_tree", "template_rotation",
           "transfer_template"]
