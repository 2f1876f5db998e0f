"""The stages of `train.py stage=...` and the edit.py / sample.py commands, one module each;
`registry.py` holds one entry per stage with everything about it (docs/contributing.md)."""
