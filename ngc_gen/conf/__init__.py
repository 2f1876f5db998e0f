"""Configs shipped inside the package, so an installed ngc-gen finds them without the checkout:
the edit programs (`edit/*.yaml`, the `edit` group of edit.py, found through Hydra's search path
`pkg://ngc_gen.conf`); and `defaults`, the torch-free reader of the checkout's conf/ YAML that
gives settings built outside a composed config their values."""
