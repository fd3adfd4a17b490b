"""An ``Sdf.Layer`` stand-in for tests: every attribute goes to the real layer, and a subclass
overrides ``Save`` (to fail as on a full disk, or to be interrupted while it runs)."""


class LayerProxy:
    def __init__(self, layer):
        object.__setattr__(self, "_layer", layer)

    def __getattr__(self, name):
        return getattr(self._layer, name)

    def __setattr__(self, name, value):
        setattr(self._layer, name, value)
