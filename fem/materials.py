"""Isotropic linear-elastic materials, read from TOML tables (built-in `data/materials.toml`)."""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from .errors import FemError

_FIELDS = ("youngs_modulus_Pa", "poisson_ratio", "density_kg_per_m3")


@dataclass(frozen=True)
class Material:
    """An isotropic linear-elastic material. SI units."""

    name: str  # id in the materials table, e.g. "al6061-t6"
    youngs_modulus_Pa: float
    poisson_ratio: float
    density_kg_per_m3: float
    yield_strength_Pa: float | None = None
    description: str = ""  # human-readable, e.g. "Aluminium 6061-T6"

    @property
    def lame_Pa(self) -> tuple[float, float]:
        """Lame's first parameter lambda and the shear modulus mu."""
        E, nu = self.youngs_modulus_Pa, self.poisson_ratio
        return E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))


def lame_ratio_low(material: Material, reference: Material) -> float:
    """The smaller of `material`'s Lame constants over `reference`'s: on one mesh K = lam A + mu B
    with A and B positive semidefinite, so K_material >= this ratio times K_reference, a lower
    bound of the eigenvalues of K_reference^-1 K_material (fem.solvers.preconditioned_cg)."""
    (lam, mu), (lam_ref, mu_ref) = material.lame_Pa, reference.lame_Pa
    return min(lam / lam_ref, mu / mu_ref)


def _number(table: dict, key: str, where: str) -> float:
    value = table.get(key)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise FemError(f"{where}: '{key}' must be a finite number, got {value!r}")
    return float(value)


def material_from_table(material_id: str, table: dict, where: str) -> Material:
    """Validate one TOML table (E > 0, -1 < nu < 0.5, rho > 0, yield > 0 if given)."""
    if not isinstance(table, dict):
        raise FemError(f"{where}: material '{material_id}' must be a table of properties")
    where = f"{where} [{material_id}]"
    E, nu, rho = (_number(table, key, where) for key in _FIELDS)
    if E <= 0:
        raise FemError(f"{where}: youngs_modulus_Pa must be > 0, got {E}")
    if not -1.0 < nu < 0.5:
        raise FemError(f"{where}: poisson_ratio must be in (-1, 0.5), got {nu}")
    if rho <= 0:
        raise FemError(f"{where}: density_kg_per_m3 must be > 0, got {rho}")
    yield_Pa = None
    if "yield_strength_Pa" in table:
        yield_Pa = _number(table, "yield_strength_Pa", where)
        if yield_Pa <= 0:
            raise FemError(f"{where}: yield_strength_Pa must be > 0, got {yield_Pa}")
    unknown = set(table) - set(_FIELDS) - {"description", "yield_strength_Pa"}
    if unknown:
        raise FemError(
            f"{where}: unknown keys {sorted(unknown)}; expected description, {', '.join(_FIELDS)}, yield_strength_Pa"
        )
    return Material(material_id, E, nu, rho, yield_Pa, str(table.get("description", "")))


def _read_toml(text: str, where: str) -> dict[str, Material]:
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise FemError(f"{where}: not valid TOML ({exc})") from None
    return {key: material_from_table(key, table, where) for key, table in data.items()}


def load_materials(extra_file: str | Path | None = None) -> dict[str, Material]:
    """The built-in materials, plus (overriding on equal ids) those of a user TOML file."""
    builtin = resources.files(__package__).joinpath("data/materials.toml").read_text(encoding="utf-8")
    materials = _read_toml(builtin, "built-in materials.toml")
    if extra_file is not None:
        path = Path(extra_file)
        try:
            text = path.read_text(encoding="utf-8")
        except OSError as exc:
            raise FemError(f"materials file {str(path)!r}: cannot read ({exc.strerror})") from None
        materials.update(_read_toml(text, f"materials file {str(path)!r}"))
    return materials


def get_material(name: str, materials: dict[str, Material] | None = None) -> Material:
    """Look a material up by id; an unknown id is a FemError naming the known ones."""
    materials = load_materials() if materials is None else materials
    try:
        return materials[name]
    except KeyError:
        raise FemError(f"unknown material {name!r}; known: {', '.join(sorted(materials))}") from None
