"""The package's shape: stages import only from earlier stages, no cycles, no long modules.

The rules and the graph are in ``tests/import_graph.py`` (``python tests/import_graph.py`` prints
the stage graph that ARCHITECTURE.md lists).
"""

from . import import_graph


def test_every_module_belongs_to_a_known_stage():
    unknown = sorted({import_graph.stage(n) for n in import_graph.modules()} - set(import_graph.STAGES))
    assert unknown == [], f"modules outside the listed stages: {unknown} (add them to STAGES)"


def test_no_import_cycles():
    assert import_graph.cycles() == []


def test_no_import_from_a_later_stage_into_an_earlier_one():
    assert import_graph.backward_imports() == []


def test_no_module_over_600_lines():
    assert import_graph.long_modules(600) == []


def test_the_checker_sees_a_backward_import_and_a_cycle(tmp_path, monkeypatch):
    """The rules can fail: a model module importing the frame loop, and two modules importing
    each other, are reported."""
    pkg = tmp_path / "warp_tube"
    (pkg / "model").mkdir(parents=True)
    (pkg / "sim").mkdir()
    (tmp_path / "kernels").mkdir()
    for d in (pkg, pkg / "model", pkg / "sim"):
        (d / "__init__.py").write_text("")
    (pkg / "model" / "a.py").write_text("from ..sim.b import x\n")
    (pkg / "sim" / "b.py").write_text("from ..model.a import y\n")
    monkeypatch.setattr(import_graph, "ROOT", tmp_path)
    assert import_graph.backward_imports() == ["warp_tube.model.a -> warp_tube.sim.b"]
    assert any("warp_tube.model.a" in c and "warp_tube.sim.b" in c for c in import_graph.cycles())
    (pkg / "model" / "long.py").write_text("x = 1\n" * 601)
    assert import_graph.long_modules(600) == ["warp_tube.model.long (601 lines)"]
