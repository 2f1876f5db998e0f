"""Shapes the project makes itself: the procedural creatures with their built-in GC template
(``creatures``) and the implicit-modelling toolkit they are built with (``implicit``)."""
