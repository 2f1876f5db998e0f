"""Generation from a skeleton benchmark: the GCs of the 16 held-out creatures (never
trained on) as conditions, 4 samples each, on the generation recipe of bench/generate.py (its
runs from that bench's fit cache, trained if the recipe has none).

    python -m bench.condition [--strength S] [--project-steps K] [--sweep]

Reports (2048 surface points per shape, squared Chamfer = sum of the two mean squared nearest
distances; every mesh in the held-out creatures' frame, no renormalisation):
  gc_err           rms decoded GC parameter error against the condition, std units of the
                   training parameters, before "replace" (mean over samples)
  cd_conditional   Chamfer of the conditioned samples (GCs replaced) to the held-out creature the
                   GCs came from
  cd_unconditional the floor: unconditional samples from the same noise (strength 0), decoded
  cd_refit         the ceiling: the creature's own latent fitted with the decoders frozen (SDF L1
                   on its samples + GC parameter loss, as the shape-latent stage trains), decoded
                   with its GCs replaced like the conditioned samples
  diversity        mean pairwise Chamfer between the 4 samples of one condition (mean over the
                   conditions); diversity_unconditional the same for unconditional samples
  s_per_sample     guided latent sampling time per sample (s_per_sample_unconditional: the
                   plain sampler, same run); mesh_s_per_sample the extraction at --resolution
--sweep adds the GC error and the spread of the decoded GCs across samples against strength
(latents only, no meshes), and the same for a partial condition (the four legs).
Writes bench/results/condition.json (with the machine record, bench/_harness.py) and
condition.png (a drawn skeleton, four shapes for it; the legs-only condition below).
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import TYPE_CHECKING

from bench import _generation as generation
from bench._harness import Bench
from bench._tables import rows_table, sci

if TYPE_CHECKING:
    import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RUNS = ROOT / "bench/runs/condition"
RESULTS = ROOT / "bench/results"
LEGS = ("leg_fl", "leg_fr", "leg_bl", "leg_br")


def defaults() -> dict:
    """The condition settings sample.py uses (conf/mode/condition.yaml), the bench's defaults."""
    from ngc_gen.app.runtime.config import compose_config

    return dict(compose_config("sample", ["mode=condition"]).condition)


def refit_latent(shape_latent, prepared, steps: int, lr: float, batch: int, seed: int):
    """A latent (1, D) for a prepared shape the decoders never saw: Adam on the shape-latent loss
    (SDF L1 through the annotated GCs' relative coordinates + param_weight * GC parameter MSE
    in std units + latent_reg ||s||^2) with the shape decoder and NGC decoder frozen."""
    import numpy as np
    import torch
    import yaml

    sl, sd, hp = shape_latent, shape_latent.shape_decoder, shape_latent.hparams
    theta = sl.template.vector(yaml.safe_load(prepared.annotation_yaml)["gcs"])
    target = sd.normalise(torch.as_tensor(theta, dtype=torch.float64)).float()
    gc = torch.from_numpy(prepared.pair_gc.astype(np.int64))
    rel = torch.from_numpy(prepared.pair_rel.astype(np.float32))
    sdf = torch.from_numpy(prepared.sdf[prepared.pair_point].astype(np.float32))
    start = sl.latents.weight.detach().mean(0, keepdim=True)
    n_fixed = sl.n_fixed  # explicit latents: the GC entries are the shape's own GCs, held
    fixed = sd.gc_part(target[None])[:, :n_fixed]
    free = start[:, n_fixed:].clone().requires_grad_(True)
    opt = torch.optim.Adam([free], lr=lr)
    g = torch.Generator().manual_seed(seed)
    for p in sl.parameters():
        p.requires_grad_(False)
    for _ in range(steps):
        idx = torch.randint(len(gc), (batch,), generator=g)
        s = torch.cat([fixed, free], 1)
        z, codes = sd(s)
        pred = sl.ngc(codes[0, gc[idx]], rel[idx])
        loss = ((pred - sdf[idx]).abs().mean()
                + hp.param_weight * ((z[0] - target)[sd.varying] ** 2).mean()
                + hp.latent_reg * (free * free).sum())
        opt.zero_grad()
        loss.backward()
        opt.step()
    for p in sl.parameters():
        p.requires_grad_(True)
    return torch.cat([fixed, free], 1).detach()


def affine_hull_residual(sd, train_theta: np.ndarray, held_theta: np.ndarray) -> float:
    """RMS distance (std units, parameters that vary in training) of held-out GC parameter
    vectors from the affine hull of the training shapes' vectors: what any decoder that maps
    latents to GCs only through the training shapes' span (the MLP head of non-explicit
    latents) leaves at least, however its latent is chosen."""
    import numpy as np
    import torch

    def z(theta):
        return sd.normalise(torch.as_tensor(theta, dtype=torch.float64))[:, sd.varying].numpy()

    zt, zh = z(train_theta), z(held_theta)
    mu = zt.mean(0)
    _, sv, vt = np.linalg.svd(zt - mu, full_matrices=False)
    basis = vt[sv > 1e-9 * sv.max()]
    r = (zh - mu) - (zh - mu) @ basis.T @ basis
    return float(np.sqrt((r ** 2).mean()))


def decoder_floor(gen, cond, steps: int = 1500, lr: float = 1e-2) -> float:
    """The lowest GC error any latent reaches: Adam on the latent alone (no prior, no bound on
    its norm) from the best training latent. What no sampler can beat with this decoder."""
    import torch

    from ngc_gen.generate.condition import gc_error, residual

    sd = gen.shape_latent.shape_decoder
    start = int(gc_error(sd, gen.train_latents, cond).argmin())
    s = gen.train_latents[start:start + 1].clone().requires_grad_(True)
    opt = torch.optim.Adam([s], lr=lr)
    for _ in range(steps):
        opt.zero_grad()
        residual(sd, s, cond).pow(2).mean().backward()
        opt.step()
    return float(gc_error(sd, s.detach(), cond)[0])


def mesh_shapes(gen, shapes, out_dir: Path, resolution: int):
    """Meshes (decoder frame, not renormalised) of decoded Shapes, written as sample.py does;
    returns (meshes, seconds per mesh)."""
    import trimesh

    from ngc_gen.app.runtime.outputs import extract_and_write

    written, secs = extract_and_write(gen, shapes, out_dir, resolution, normalised=False,
                                      progress=False)
    return [trimesh.load(w.mesh, process=False) for w in written], secs


def clouds(meshes, n_points: int):
    return generation.clouds(meshes, n_points, 0)


def spread(gen, latents, names) -> float:
    """Mean over the named GCs' varying parameters of their std across samples (std units)."""
    import torch

    sd = gen.shape_latent.shape_decoder
    with torch.no_grad():
        z = sd(latents)[0]
    cols = [z[:, sl][:, sd.varying[sl]] for n, _, sl in gen.shape_latent.template.fields()
            if n in names]
    z = torch.cat(cols, 1)
    return float(z.std(0).mean()) if len(z) > 1 else 0.0


def sweep(gen, conds, args) -> list[dict]:
    """GC error and GC spread across samples against strength, full and legs-only conditions."""
    import numpy as np

    from ngc_gen.generate.condition import condition_from_gcs, conditional_latents, gc_error

    sd, template = gen.shape_latent.shape_decoder, gen.shape_latent.template
    others = [n for n in template.names if n not in LEGS]
    rows = []
    for strength in args.sweep_strengths:
        for project in args.sweep_project:
            if strength == 0 and project > 0:
                continue
            row = {"strength": strength, "project_steps": project}
            for kind in ("full", "legs"):
                errs, sp_c, sp_o, t = [], [], [], 0.0
                for k, (name, cond) in enumerate(conds):
                    if kind == "legs":
                        cond = condition_from_gcs(template, [d for d in cond.gcs
                                                             if d["name"] in LEGS])
                    t0 = time.perf_counter()
                    z = conditional_latents(gen, cond, range(args.sweep_per_condition),
                                            args.seed * 1000 + k, strength, project)
                    t += time.perf_counter() - t0
                    errs.append(float(gc_error(sd, z, cond).mean()))
                    if kind == "legs":
                        sp_c.append(spread(gen, z, LEGS))
                        sp_o.append(spread(gen, z, others))
                row[kind] = {"gc_err": float(np.mean(errs)),
                             "s_per_sample": t / (len(conds) * args.sweep_per_condition)}
                if kind == "legs":
                    row[kind].update(spread_legs=float(np.mean(sp_c)),
                                     spread_others=float(np.mean(sp_o)))
            rows.append(row)
            print(f"strength {strength:6.1f} project {project}: gc_err full "
                  f"{row['full']['gc_err']:.3f}, legs {row['legs']['gc_err']:.3f} "
                  f"(spread legs {row['legs']['spread_legs']:.3f}, others "
                  f"{row['legs']['spread_others']:.3f} std), "
                  f"{1e3 * row['full']['s_per_sample']:.0f} ms/sample", flush=True)
    return rows


def render(rows, path: Path) -> None:
    """rows of (given GCs as a mesh, [shapes], [titles]): one row each, one scale per row."""
    from ngc_gen.viz import render_grid

    render_grid([[g] + shapes for g, shapes, _ in rows], path,
                titles=[titles for _, _, titles in rows], frame="row")


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    generation.recipe_args(ap)  # the generate bench's recipe: its runs are reused
    ap.add_argument("--per-condition", type=int, default=4, help="samples per condition")
    ap.add_argument("--limit", type=int, default=None, help="use only the first held-out shapes")
    ap.add_argument("--strength", type=float, default=None, help="default: conf/sample.yaml")
    ap.add_argument("--project-steps", type=int, default=None, help="default: conf/sample.yaml")
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--points", type=int, default=2048)
    ap.add_argument("--refit-steps", type=int, default=400)
    ap.add_argument("--refit-lr", type=float, default=1e-2)
    ap.add_argument("--sweep", action="store_true", help="GC error vs strength (latents only)")
    ap.add_argument("--sweep-strengths", type=float, nargs="+",
                    default=[0.0, 1.0, 3.0, 10.0, 30.0, 100.0])
    ap.add_argument("--sweep-project", type=int, nargs="+", default=[0, 2])
    ap.add_argument("--sweep-per-condition", type=int, default=2)
    ap.add_argument("--threads", type=int, default=1)
    return ap.parse_args()


def gc_objects(dicts):
    from ngc_gen.geometry import GeneralizedCylinder

    return [GeneralizedCylinder.from_dict(d) for d in dicts]


def samples(gen, conds, data_dir: Path, args, strength: float, project: int) -> dict:
    """Per condition: conditioned and unconditioned samples (the same noise) meshed, the
    held-out creature's own latent refitted, GC errors, sampling seconds and the picture's
    first row."""
    from ngc_gen.data.annotations import load_annotation
    from ngc_gen.data.prepare import PrepareSettings, prepare_shape
    from ngc_gen.generate.condition import conditional_latents, gc_error, with_given_gcs
    from ngc_gen.generate.shapes import decode_shapes
    from ngc_gen.viz import gcs_surface

    sd, n_per = gen.shape_latent.shape_decoder, args.per_condition
    out = {k: [] for k in ("cond_meshes", "plain_meshes", "refit_meshes", "errs", "errs_u",
                           "floors", "mesh_secs", "picture")}
    out["t_cond"] = out["t_plain"] = 0.0
    settings = PrepareSettings.from_yaml(n_samples=args.samples)
    cache = ROOT / f".cache/prepared/creatures_gen{args.samples // 1000}k_heldout"
    for k, (name, cond) in enumerate(conds):
        seed = args.seed * 1000 + k
        t0 = time.perf_counter()
        z = conditional_latents(gen, cond, range(n_per), seed, strength, project)
        out["t_cond"] += time.perf_counter() - t0
        t0 = time.perf_counter()
        z0 = gen.sample_latents(range(n_per), seed)
        out["t_plain"] += time.perf_counter() - t0
        out["errs"].append(gc_error(sd, z, cond).numpy())
        out["errs_u"].append(gc_error(sd, z0, cond).numpy())
        out["floors"].append(decoder_floor(gen, cond))
        shapes = [with_given_gcs(s, cond) for s in
                  decode_shapes(gen.shape_latent, z, [f"{name}_c{i}" for i in range(n_per)])]
        m, secs = mesh_shapes(gen, shapes, RUNS / "conditional", args.resolution)
        out["cond_meshes"].append(m)
        out["mesh_secs"] += secs
        m, _ = mesh_shapes(gen, decode_shapes(gen.shape_latent, z0, [f"{name}_u{i}" for i in
                                                                       range(n_per)]),
                           RUNS / "unconditional", args.resolution)
        out["plain_meshes"].append(m)
        prepared = prepare_shape(load_annotation(data_dir / f"{name}.yaml"), settings, cache)
        s_fit = refit_latent(gen.shape_latent, prepared, args.refit_steps, args.refit_lr,
                             args.batch_size or generation.compose_batch_size(), args.seed)
        fit = decode_shapes(gen.shape_latent, s_fit, [f"{name}_refit"])[0]
        fit = with_given_gcs(fit, cond)
        out["refit_meshes"].append(mesh_shapes(gen, [fit], RUNS / "refit", args.resolution)[0][0])
        if k == 0:
            out["picture"].append((gcs_surface(gc_objects(list(cond.gcs))), out["cond_meshes"][-1],
                                   [f"{name}: all GCs"] + [f"sample {i}" for i in range(n_per)]))
        print(f"{k + 1:2d}/{len(conds)} {name}: gc_err {out['errs'][-1].mean():.3f} std (decoder "
              f"floor {out['floors'][-1]:.3f})", flush=True)
    return out


def metrics(s: dict, held: list, data_dir: Path, args) -> dict:
    """The result's figures from `samples`' output against the held-out creatures' meshes."""
    import numpy as np
    import trimesh

    from ngc_gen.eval import pairwise_chamfer

    n_per = args.per_condition
    gt = [trimesh.load(data_dir / f"{n}.ply", process=False) for n in held]
    gt_pts, _ = clouds(gt, args.points)
    cd_c, cd_u, cd_r, div_c, div_u = [], [], [], [], []
    empty = {"conditional": 0, "unconditional": 0, "refit": 0}
    for k in range(len(held)):
        pc, e = clouds(s["cond_meshes"][k], args.points)
        empty["conditional"] += e
        pu, e = clouds(s["plain_meshes"][k], args.points)
        empty["unconditional"] += e
        pr, e = clouds([s["refit_meshes"][k]], args.points)
        empty["refit"] += e
        cd_c.append(pairwise_chamfer(pc, gt_pts[k:k + 1]).mean())
        cd_u.append(pairwise_chamfer(pu, gt_pts[k:k + 1]).mean())
        cd_r.append(pairwise_chamfer(pr, gt_pts[k:k + 1]).mean())
        iu = np.triu_indices(n_per, 1)
        div_c.append(pairwise_chamfer(pc)[iu].mean())
        div_u.append(pairwise_chamfer(pu)[iu].mean())
    n_samples = len(held) * n_per
    errs, errs_u, floors = s["errs"], s["errs_u"], s["floors"]
    return {
        "gc_err": float(np.mean(np.concatenate(errs))),
        "gc_err_max": float(np.max(np.concatenate(errs))),
        "gc_err_decoder_floor": float(np.mean(floors)),
        "gc_err_unconditional": float(np.mean(np.concatenate(errs_u))),
        "cd_conditional": float(np.mean(cd_c)), "cd_unconditional": float(np.mean(cd_u)),
        "cd_refit": float(np.mean(cd_r)), "diversity": float(np.mean(div_c)),
        "diversity_unconditional": float(np.mean(div_u)),
        "s_per_sample": s["t_cond"] / n_samples,
        "s_per_sample_unconditional": s["t_plain"] / n_samples,
        "mesh_s_per_sample": float(np.mean(s["mesh_secs"])),
        "per_condition": {n: {"gc_err": float(e.mean()), "gc_err_floor": f,
                              "cd_conditional": float(c),
                              "cd_unconditional": float(u), "cd_refit": float(r),
                              "diversity": float(d)}
                          for n, e, f, c, u, r, d in zip(held, errs, floors, cd_c, cd_u,
                                                         cd_r, div_c)},
        "empty_meshes": empty}


def legs_row(gen, conds, args, strength: float, project: int):
    """The picture's second row: samples given the first condition's legs only."""
    from ngc_gen.generate.condition import (condition_from_gcs, conditional_latents,
                                            with_given_gcs)
    from ngc_gen.generate.shapes import decode_shapes
    from ngc_gen.viz import gcs_surface

    n_per = args.per_condition
    name0, cond0 = conds[0]
    legs = condition_from_gcs(gen.shape_latent.template,
                              [d for d in cond0.gcs if d["name"] in LEGS])
    z = conditional_latents(gen, legs, range(n_per), args.seed * 1000, strength, project)
    shapes = [with_given_gcs(s, legs) for s in
              decode_shapes(gen.shape_latent, z, [f"{name0}_legs{i}" for i in range(n_per)])]
    legs_meshes, _ = mesh_shapes(gen, shapes, RUNS / "legs", args.resolution)
    return (gcs_surface(gc_objects(list(legs.gcs))), legs_meshes,
            [f"{name0}: legs only"] + [f"sample {i}" for i in range(n_per)])


def main():
    import numpy as np

    args = parse_args()
    bench = Bench("condition")

    import torch
    import yaml

    torch.set_num_threads(args.threads)

    from ngc_gen.data.datasets import Creatures
    from ngc_gen.generate import load_generator
    from ngc_gen.generate.condition import load_condition

    conf = defaults()
    strength = conf["strength"] if args.strength is None else args.strength
    project = conf["project_steps"] if args.project_steps is None else args.project_steps
    t_start = time.perf_counter()
    data = Creatures("creatures", ROOT / f".cache/datasets/creatures_n{args.n}_s{args.seed}",
                     n=args.n, seed=args.seed, test_fraction=args.test_fraction)
    data.shapes()
    split = json.loads((data.out_dir / "split.json").read_text())
    held = split["test"][:args.limit]
    print(f"{len(held)} held-out creatures as conditions, {args.per_condition} samples each; "
          f"strength {strength}, project_steps {project}")
    runs = generation.train(args)           # bench/generate.py's runs (from its fit cache)
    gen = load_generator(runs["diffusion_dir"])
    sd, template = gen.shape_latent.shape_decoder, gen.shape_latent.template
    conds = [(n, load_condition(data.out_dir / f"{n}.yaml", template)) for n in held]
    res = {"n_conditions": len(held), "samples_per_condition": args.per_condition,
           "strength": strength, "project_steps": project, "resolution": args.resolution,
           "points": args.points, "seed": args.seed, "threads": args.threads,
           "convention": "gc_err: rms over the conditioned GC parameters that vary in training, "
                         "std units, before replace; Chamfer: 2048 surface points, squared, sum "
                         "of the two means, in the held-out creatures' frame (no "
                         "renormalisation); diversity: mean pairwise Chamfer of the samples of "
                         "one condition; s_per_sample: guided latent sampling per sample"}
    if args.sweep:
        res["sweep"] = sweep(gen, conds, args)
    theta = {n: template.vector(yaml.safe_load((data.out_dir / f"{n}.yaml").read_text())["gcs"])
             for n in split["train"] + held}
    res["gc_affine_hull_residual"] = affine_hull_residual(
        sd, np.stack([theta[n] for n in split["train"]]), np.stack([theta[n] for n in held]))
    res["latent_layout"] = ("explicit: [GC parameters, free entries]" if sd.explicit else
                            "MLP head: latent -> GC parameters")
    s = samples(gen, conds, data.out_dir, args, strength, project)
    res.update(metrics(s, held, data.out_dir, args))
    res["total_s"] = time.perf_counter() - t_start
    res["targets"] = {"gc_err <= 0.1": res["gc_err"] <= 0.1,
                      "cd_conditional * 3 <= cd_unconditional":
                          3 * res["cd_conditional"] <= res["cd_unconditional"]}
    RESULTS.mkdir(parents=True, exist_ok=True)
    render(s["picture"] + [legs_row(gen, conds, args, strength, project)],
           RESULTS / "condition.png")
    path = bench.write(res)
    print(f"\ngc_err {res['gc_err']:.3f} std (max {res['gc_err_max']:.3f}, unconditional "
          f"{res['gc_err_unconditional']:.3f}, decoder floor {res['gc_err_decoder_floor']:.3f}); "
          f"Chamfer (x1e-3) "
          f"conditional {1e3 * res['cd_conditional']:.3f}, unconditional "
          f"{1e3 * res['cd_unconditional']:.3f}, refit {1e3 * res['cd_refit']:.3f}; diversity "
          f"{1e3 * res['diversity']:.3f} (unconditional "
          f"{1e3 * res['diversity_unconditional']:.3f}); "
          f"{1e3 * res['s_per_sample']:.0f} ms/sample guided vs "
          f"{1e3 * res['s_per_sample_unconditional']:.0f} plain; load {bench.load_before}")
    print(f"targets: {res['targets']}; total {res['total_s'] / 60:.1f} min; {path}")


# ---- the table (bench/README.md) and the headline (README.md), from the result ----------
def table(r: dict) -> str:
    e3 = lambda x: f"{1e3 * x:.2f}"  # noqa: E731
    lines = rows_table(
        [f"strength {r['strength']:g}, project_steps {r['project_steps']}, "
         f"{r['n_conditions']} conditions x {r['samples_per_condition']} samples", "value"],
        [["decoded GC error before replace (rms, std units)",
          f"{r['gc_err']:.3f} (max {r['gc_err_max']:.3f}; unconditional "
          f"{r['gc_err_unconditional']:.3f}; best any latent reaches: "
          f"{r['gc_err_decoder_floor']:.3f})"],
         ["Chamfer to the creature the GCs came from (x1e-3)", e3(r["cd_conditional"])],
         ["unconditional samples, same noise (floor)", e3(r["cd_unconditional"])],
         ["the creature's own latent refitted, decoders frozen, GCs replaced (ceiling)",
          e3(r["cd_refit"])],
         ["diversity: mean pairwise Chamfer of one condition's samples (x1e-3)",
          f"{e3(r['diversity'])} (unconditional {e3(r['diversity_unconditional'])})"],
         ["latent sampling per sample", f"{r['s_per_sample']:.2f} s guided, "
                                        f"{r['s_per_sample_unconditional']:.2f} s plain"],
         ["GC vectors of the held-out creatures outside the training shapes' affine hull (rms, "
          "std units)", f"{r['gc_affine_hull_residual']:.2f}"]])
    sweep = r.get("sweep")
    if sweep:
        strengths = sorted({row["strength"] for row in sweep})
        at = {(row["strength"], row["project_steps"]): row for row in sweep}
        projects = sorted({row["project_steps"] for row in sweep})
        body = []
        for p in projects:
            suffix = "" if p == 0 else f", `project_steps={p}`"
            for kind, label in (("full", "all GCs given"), ("legs", "legs given")):
                body.append([f"GC error, {label}{suffix}"] + [
                    f"{at[s, p][kind]['gc_err']:.3f}" if (s, p) in at else "" for s in strengths])
            body.append([f"legs given{suffix}: spread of the legs / other GCs"] + [
                f"{at[s, p]['legs']['spread_legs']:.2f} / {at[s, p]['legs']['spread_others']:.2f}"
                if (s, p) in at else "" for s in strengths])
        lines += [""] + rows_table(["strength"] + [f"{s:g}" for s in strengths], body)
    return "\n".join(lines)


def headline(r):
    return (f"GC error {r['gc_err']:.3f} std; Chamfer to the source {sci(r['cd_conditional'])} vs "
            f"{sci(r['cd_unconditional'])} unconditioned")


if __name__ == "__main__":
    main()
