"""Meshes as the data layer reads them: file I/O and normalisation (``io``), a closed proxy of
any mesh (``proxy``), signed distance with a winding-number sign (``sdf``) and the surface,
membership and volume samplers (``sampling``)."""
