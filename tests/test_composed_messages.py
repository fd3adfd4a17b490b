"""Errors in values the scene composes from elsewhere: a value authored in a referenced file, a
payload, a sublayer or another prim of the scene is named where it was authored, as well as where
the scene has it; a required attribute authored only in the variants of a variantSet with no
selection is said to be so."""

from __future__ import annotations

import pytest

from warp_tube.cli import main
from warp_tube.scene.spec import SceneError
from warp_tube.scene.usd import load_scene

from .test_usd_interop import BODY, HEADER, tube, world

BAD_DENSITY = BODY.replace("warptube:density = 1050", "warptube:density = -1")
ASSET = '#usda 1.0\n(\n    defaultPrim = "Asset"\n    metersPerUnit = 0.01\n    upAxis = "Y"\n)\n' + tube(BAD_DENSITY, name="Asset")
NOT_POSITIVE = "found -1.0: expected a number > 0"


def _error(path) -> str:
    with pytest.raises(SceneError) as err:
        load_scene(str(path))
    return str(err.value)


@pytest.mark.parametrize("arc", ["references", "payload"])
def test_a_bad_value_in_a_referenced_file_names_that_file_and_its_prim(arc, tmp_cwd, capsys):
    """The message named only the top scene and the composed prim: the file to edit, and the prim
    in it, were left to find."""
    (tmp_cwd / "assets").mkdir()
    (tmp_cwd / "assets" / "asset.usda").write_text(ASSET)
    (tmp_cwd / "shot").mkdir()
    (tmp_cwd / "shot" / "scene.usda").write_text(HEADER + world(f'def "T1" ({arc} = @../assets/asset.usda@)\n{{\n}}\n'))
    assert _error("shot/scene.usda") == ("shot/scene.usda: /World/T1.warptube:density (authored in ../assets/asset.usda "
                                         f"at /Asset.warptube:density): {NOT_POSITIVE}")  # fmt: skip
    assert main(["run", "shot/scene.usda", "-o", "out.usdc", "--quiet"]) == 2
    assert "(authored in ../assets/asset.usda at /Asset.warptube:density)" in capsys.readouterr().err
    assert not (tmp_cwd / "out.usdc").exists()


def test_a_bad_value_in_a_sublayer_names_the_sublayer(tmp_cwd):
    (tmp_cwd / "sub.usda").write_text(HEADER + world(tube(BAD_DENSITY)))
    (tmp_cwd / "scene.usda").write_text(HEADER.replace("(\n", "(\n    subLayers = [@sub.usda@]\n", 1))
    assert _error("scene.usda") == f"scene.usda: /World/Tube.warptube:density (authored in sub.usda): {NOT_POSITIVE}"


def test_a_stronger_opinion_in_the_scene_over_a_referenced_one_is_named_as_the_scenes(tmp_cwd):
    """Where the scene overrides the referenced value, the scene's own value is the one at fault."""
    (tmp_cwd / "asset.usda").write_text(ASSET.replace("warptube:density = -1", "warptube:density = 1050"))
    over = 'def "T1" (references = @asset.usda@)\n{\n    double warptube:density = -1\n}\n'
    (tmp_cwd / "scene.usda").write_text(HEADER + world(over))
    assert _error("scene.usda") == f"scene.usda: /World/T1.warptube:density: {NOT_POSITIVE}"


def test_a_bad_value_in_another_prim_of_the_scene_names_that_prim(tmp_cwd):
    """A tube referencing a class prim of the same file: where in the file the value is."""
    proto = tube(BAD_DENSITY, name="Proto").replace("def BasisCurves", "class BasisCurves")
    (tmp_cwd / "scene.usda").write_text(HEADER + proto + world('def "Copy" (references = </Proto>)\n{\n}\n'))
    assert _error("scene.usda") == f"scene.usda: /World/Copy.warptube:density (authored at /Proto.warptube:density): {NOT_POSITIVE}"


def test_a_misspelled_attribute_in_a_referenced_file_names_that_file(tmp_cwd):
    (tmp_cwd / "asset.usda").write_text(ASSET.replace("warptube:density = -1", "warptube:densty = 1050"))
    (tmp_cwd / "scene.usda").write_text(HEADER + world('def "T1" (references = @asset.usda@)\n{\n}\n'))
    message = _error("scene.usda")
    assert message.startswith("scene.usda: /World/T1.warptube:densty (authored in asset.usda at /Asset.warptube:densty): "
                              "unknown attribute: did you mean warptube:density?"), message  # fmt: skip


def _variants(where: str, selection: str = "") -> str:
    """The default tube with its Young's modulus authored only in the variants soft and stiff of the
    variantSet stiffness on the prim ``where`` (``Tube`` or ``World``), selected or not."""
    body = BODY.replace("        double warptube:youngsModulus = 100000\n", "")
    variants = ('    variantSet "stiffness" = {\n'
                '        "soft" {\n%s\n        }\n        "stiff" {\n%s\n        }\n        "none" {\n        }\n    }\n')  # fmt: skip
    sel = f'    variants = {{\n        string stiffness = "{selection}"\n    }}\n' if selection else ""
    meta = f' (\n    prepend variantSets = "stiffness"\n{sel})'
    if where == "Tube":
        value = "            double warptube:youngsModulus = %s"
        return HEADER + world(tube(body + variants % (value % 1e5, value % 1e8), meta=meta))
    value = '            over "Tube" {\n                double warptube:youngsModulus = %s\n            }'
    return HEADER + world(tube(body) + variants % (value % 1e5, value % 1e8), meta=meta)


@pytest.mark.parametrize("where", ["Tube", "World"])
def test_a_required_attribute_only_in_unselected_variants_is_said_to_be_so(where, tmp_cwd, capsys):
    """It was reported missing, as if nowhere authored: the variantSet with no selection was left
    to find."""
    (tmp_cwd / "scene.usda").write_text(_variants(where))
    holder = "/World/Tube" if where == "Tube" else "/World"
    assert _error("scene.usda") == (
        f'scene.usda: /World/Tube.warptube:youngsModulus: missing (variantSet "stiffness" on {holder} has no selection; '
        "its variants soft, stiff author it: select one): expected youngsModulus [Pa], or both warptube:stretchStiffness "
        "[N] and warptube:bendStiffness [N m^2]")  # fmt: skip
    assert main(["run", "scene.usda", "-o", "out.usdc", "--quiet"]) == 2
    assert "has no selection" in capsys.readouterr().err and not (tmp_cwd / "out.usdc").exists()
    (tmp_cwd / "scene.usda").write_text(_variants(where, selection="stiff"))
    assert load_scene("scene.usda").tubes[0].params.youngs_modulus == 1e8
    (tmp_cwd / "scene.usda").write_text(_variants(where, selection="none"))  # selected: missing, as before
    assert _error("scene.usda").startswith("scene.usda: /World/Tube.warptube:youngsModulus: missing: expected")


def test_a_variant_selection_that_names_no_variant_is_said_to_be_so(tmp_cwd):
    """A selection misspelled ("stif"): USD composes no variant, and the modulus only the variants
    author was reported missing with nothing to find the typo by."""
    (tmp_cwd / "scene.usda").write_text(_variants("Tube", selection="stif"))
    assert _error("scene.usda") == (
        'scene.usda: /World/Tube.warptube:youngsModulus: missing (variantSet "stiffness" on /World/Tube selects "stif", '
        "which it does not have; its variants soft, stiff author it: select one): expected youngsModulus [Pa], or both "
        "warptube:stretchStiffness [N] and warptube:bendStiffness [N m^2]")  # fmt: skip
