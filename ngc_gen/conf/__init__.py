"""Configs shipped inside the package, so an installed ngc-gen finds them without the checkout:
the edit programs (`edit/*.yaml`, the `edit` group of edit.py, found through Hydra's search path
`pkg://ngc_gen.conf`). Data only: no code imports from here."""
