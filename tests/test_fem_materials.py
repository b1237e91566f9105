import pytest

from fem import FemError, Material, load_materials
from fem.materials import get_material


def test_builtin_materials_have_the_issue_values():
    materials = load_materials()
    assert materials["al6061-t6"] == Material("al6061-t6", 68.9e9, 0.33, 2700.0, 276e6, "Aluminium 6061-T6")
    ti = materials["ti-grade2"]
    assert (ti.youngs_modulus_Pa, ti.poisson_ratio, ti.density_kg_per_m3, ti.yield_strength_Pa) == (
        105e9,
        0.37,
        4510.0,
        275e6,
    )
    assert any(key.startswith("steel") for key in materials)


def test_lame_parameters():
    lam, mu = get_material("al6061-t6").lame_Pa
    E, nu = 68.9e9, 0.33
    assert mu == pytest.approx(E / (2 * (1 + nu)), rel=1e-15)
    assert lam == pytest.approx(E * nu / ((1 + nu) * (1 - 2 * nu)), rel=1e-15)


def test_user_file_adds_and_overrides(tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text(
        '[pa12]\ndescription = "Nylon"\nyoungs_modulus_Pa = 1.7e9\npoisson_ratio = 0.4\ndensity_kg_per_m3 = 1010\n'
    )
    materials = load_materials(path)
    assert materials["pa12"].youngs_modulus_Pa == 1.7e9
    assert materials["pa12"].yield_strength_Pa is None
    assert "al6061-t6" in materials


@pytest.mark.parametrize(
    "body, fragment",
    [
        ("youngs_modulus_Pa = -1\npoisson_ratio = 0.3\ndensity_kg_per_m3 = 1", "youngs_modulus_Pa must be > 0"),
        ("youngs_modulus_Pa = 1e9\npoisson_ratio = 0.5\ndensity_kg_per_m3 = 1", "poisson_ratio"),
        ("youngs_modulus_Pa = 1e9\npoisson_ratio = -1.0\ndensity_kg_per_m3 = 1", "poisson_ratio"),
        ("youngs_modulus_Pa = 1e9\npoisson_ratio = 0.3\ndensity_kg_per_m3 = 0", "density_kg_per_m3"),
        ("youngs_modulus_Pa = 1e9\npoisson_ratio = 0.3", "density_kg_per_m3"),
        ('youngs_modulus_Pa = "x"\npoisson_ratio = 0.3\ndensity_kg_per_m3 = 1', "finite number"),
        ("youngs_modulus_Pa = 1e9\npoisson_ratio = 0.3\ndensity_kg_per_m3 = 1\ncolour = 1", "unknown keys"),
    ],
)
def test_invalid_user_material_is_a_fem_error_naming_file_and_material(tmp_path, body, fragment):
    path = tmp_path / "bad.toml"
    path.write_text(f"[bad]\n{body}\n")
    with pytest.raises(FemError, match=fragment) as info:
        load_materials(path)
    assert "bad.toml" in str(info.value) and "[bad]" in str(info.value)


def test_unreadable_or_invalid_toml_file(tmp_path):
    with pytest.raises(FemError, match="cannot read"):
        load_materials(tmp_path / "missing.toml")
    broken = tmp_path / "broken.toml"
    broken.write_text("[x\n")
    with pytest.raises(FemError, match="not valid TOML"):
        load_materials(broken)


def test_unknown_material_names_the_known_ones():
    with pytest.raises(FemError, match="unknown material 'unobtainium'; known: .*al6061-t6.*ti-grade2"):
        get_material("unobtainium")
