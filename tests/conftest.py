"""Shared fixtures and builders for the tests (CPU, small sizes)."""

from __future__ import annotations

import os
import pathlib

import numpy as np
import pytest
import warp as wp

from warp_tube.bench.problems import settle, straight_points  # noqa: F401 (shared by the tests)

wp.config.log_level = wp.LOG_WARNING

ROOT = pathlib.Path(__file__).resolve().parents[1]
# ../shared beside the checkout (meshes, output checker); WARP_TUBE_SHARED points elsewhere.
SHARED = pathlib.Path(os.environ.get("WARP_TUBE_SHARED", ROOT.parent / "shared"))
SCENES = ROOT / "scenes"
CHECK_OUTPUT = SHARED / "checks" / "check_output.py"

needs_shared = pytest.mark.skipif(not SHARED.is_dir(), reason="../shared is not beside this checkout")


def check_output_problems(path, scene=None, require_surface=False):
    """Problems that ../shared/checks/check_output.py finds in an output stage (list of str)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("check_output", CHECK_OUTPUT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return list(mod.problems(str(path), str(scene) if scene else None, require_surface))


@pytest.fixture
def tmp_cwd(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    return tmp_path
