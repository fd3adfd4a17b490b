"""Centerline extraction from a tube mesh (the paper's distance mapping): mesh reading (:mod:`.mesh_io`),
the distance field (:mod:`.distance_map`), the path and its resampling (:mod:`.pipeline`,
:mod:`.polyline`), side branches (:mod:`.branches`), fidelity (:mod:`.fidelity`), the scene it writes
(:mod:`.usd`) and the command (:mod:`.command`)."""
