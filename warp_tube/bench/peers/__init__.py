"""Adapters that run the benchmark problems on other rod simulators, when they are installed
(``pip install "warp-tube[peers]"``): :mod:`.pyelastica_runner`, :mod:`.newton_runner`."""
