"""Every case of tests/bad_inputs.py: its exit status (or exception), no traceback, no C++ text, no
repeated ``file: prim:`` prefix, no file lost or left behind; and the table in BAD_INPUTS.md is their output."""

import pytest

from . import bad_inputs as bi
from .conftest import ROOT

CASES = bi.cases()


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    base = tmp_path_factory.mktemp("bad_inputs")
    fixtures = bi.make_fixtures(base / "fixtures")
    return [bi.run_case(case, fixtures, base / f"case{k:03d}") for k, case in enumerate(CASES)]


def test_the_table_covers_every_command_with_at_least_60_cases():
    assert len(CASES) >= 60
    assert {c.command for c in CASES} == {"run", "check", "extract", "preview", "export", "API"}


@pytest.mark.parametrize("k", range(len(CASES)), ids=[f"{c.command}: {c.what}" for c in CASES])
def test_case(results, k):
    r = results[k]
    assert r.traceback == "", r.traceback
    assert r.got == r.case.expect, r.message
    assert r.lost == [], f"files changed or lost: {r.lost}"
    assert r.stray == [], f"files left behind: {r.stray}"
    assert r.forbidden == [], f"C++ or traceback text shown: {r.forbidden}"
    assert r.repeated == [], f"prefix repeated in: {r.message}"
    assert r.message, "no message"


def _rows(text):
    return [[c.strip() for c in line.strip().strip("|").split(" | ")] for line in text.splitlines()[2:]]


def test_readme_table_is_the_output_of_the_cases(results):
    readme = bi.readme_table((ROOT / "BAD_INPUTS.md").read_text())
    generated = bi.table(results)
    hint = "refresh it: .venv/bin/python -m tests.bad_inputs --write BAD_INPUTS.md"
    got, want = _rows(readme), _rows(generated)
    assert len(got) == len(want), hint
    for case, g, w in zip(CASES, got, want):
        if case.machine:  # e.g. the number of CUDA devices found
            g, w = g[:3], w[:3]
        assert g == w, f"{case.command}: {case.what}: BAD_INPUTS.md {g} != {w}; {hint}"
