"""How warp_tube meets Warp and the terminal, under every stage: Warp started quietly (:mod:`.warp_setup`,
:mod:`.native_output`), a frame's launches captured once and replayed (:mod:`.replay`), and signs of
life for long phases (:mod:`.progress`)."""

from .submodules import lazy_submodules

__getattr__ = lazy_submodules(__name__)  # its modules, imported on first use
