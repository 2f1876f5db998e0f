"""The benchmarks, each run as `python -m bench.<name>` (or `make bench-<name>`).

`BENCHES` is the one list of them, in the order `make bench` runs them: a bench comes after
the benches whose cached fits it reads (extract and sparse_settings read deform's fit,
sparse_settings autogc's, condition and reconstruct generate's, fit_ablation fit's ceiling).
bench/report.py renders a table block for each of them (and a headline in the README for each
that has one) by calling the `table(result)` and `headline(result)` of its module.

Standard library only: `make bench-report` and `python -m bench` run under a bare python3.
"""

BENCHES = ("geometry", "up_axis", "fit", "fit_ablation", "seams", "deform", "extract", "autogc",
           "sparse_settings", "editor", "generate", "condition", "reconstruct", "ddp", "demo",
           "cli", "animals", "transfer", "zeroad_collection", "collection",
           "export")
