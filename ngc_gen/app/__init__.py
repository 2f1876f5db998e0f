"""Runners: what train.py (stages), edit.py and sample.py do with a composed config: read runs
and checkpoints, write run files, print tables, draw pictures (docs/architecture.md).

The top layer: it imports every library layer and none imports it. Only this layer and the entry
points change process-wide state (torch threads, logging handlers, warning filters, OmegaConf
resolvers)."""
