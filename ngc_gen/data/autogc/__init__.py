"""GCs for a mesh without an annotation: closed proxy -> curve skeleton (``skeleton``) -> branch
graph (``branches``, ``protrusions``) -> one GC per branch (``branch_gc``, ``radii``) -> names
(``names``) -> growth until the GCs cover the surface (``coverage``). ``auto`` holds the two
methods and their settings; ``fit_gc`` fits one curved GC to a separate piece."""
