"""Centerline extraction from a tube mesh (the paper's distance mapping): mesh reading (:mod:`.mesh_io`),
the queries on it (:mod:`.queries`), the distance field (:mod:`.distance_map`), the tube's ends
(:mod:`.ends`), cross-sections and spokes (:mod:`.sections`), the pipeline and its resampling
(:mod:`.pipeline`, :mod:`.polyline`), rings the inner-bend guard leaves alone (:mod:`.rings`), side
branches (:mod:`.branches`), fidelity of the simulator's rest surface (:mod:`.fidelity`), the
tube-likeness check (:mod:`.tubelike`) with closed rings (:mod:`.closed_ring`), the scene it writes
(:mod:`.usd`), the command (:mod:`.command`) and the counts in its messages (:mod:`.wording`)."""

from ..runtime.submodules import lazy_submodules

__getattr__ = lazy_submodules(__name__)  # its modules, imported on first use
