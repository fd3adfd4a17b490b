"""The package's shape: stages import only from earlier stages, no cycles, no long modules.

The rules and the graph are in ``tests/import_graph.py`` (``python tests/import_graph.py`` prints
the stage graph that ARCHITECTURE.md lists).
"""

from pathlib import Path

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


def test_a_checkout_that_shadows_an_installed_package_finds_its_kernels(tmp_path):
    """``kernels/`` is installed as ``warp_tube.kernels``; Python started at the root of a checkout
    whose package is installed elsewhere (not in place) imports ``warp_tube`` from the checkout,
    which has no ``warp_tube/kernels``: the package takes them from beside it. Here the checkout is
    a copy of the tree and the in-place install's finder is left out of the import system."""
    import shutil
    import subprocess
    import sys

    root = Path(__file__).resolve().parents[1]
    shutil.copytree(root / "warp_tube", tmp_path / "warp_tube", ignore=shutil.ignore_patterns("kernels", "__pycache__"))
    shutil.copytree(root / "kernels", tmp_path / "kernels", ignore=shutil.ignore_patterns("__pycache__"))
    code = ("import sys; sys.meta_path[:] = [f for f in sys.meta_path if 'editable' not in repr(f).lower()]; "
            "import warp_tube.kernels.contact as c, warp_tube; print(c.__file__); print(warp_tube.__file__)")  # fmt: skip
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    kernels, package = out.stdout.split()
    assert Path(kernels) == tmp_path / "kernels" / "contact.py" and Path(package) == tmp_path / "warp_tube" / "__init__.py"
