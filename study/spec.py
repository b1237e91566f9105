"""The study file (TOML): its schema, read and validated into a `StudySpec`.

Every problem is one line naming the key, what was expected and what was found (`StudyError`);
nothing is written before the whole file is valid. The schema, by table:

    [study]        name, report_best (full pipeline reports for that many best designs)
    [variables]    NAME = {min = A, max = B} (a range) | [v1, v2, ...] (a list) | "all" (cam only)
    [fixed]        NAME = value (a variable held at one value)
                   geometry = "link.step" (the link's STEP file, relative to the study file; or in
                   [variables] a list of them: CAD variants), with the part options of pipeline.py
                   bores, pitch, bore_radius, body, hardware_material, hardware_from_step (same
                   values and units as on its command line: mm in the CAD file's frame)
    [settings]     mesh_size_m, order, samples_per_degree, solver, station, settling_band_m,
                   steady_state, fea_cache
    [sampling]     method = "grid" | "lhs" | "sobol", levels (grid), points (lhs, sobol), seed
    [[constraints]] metric, and min / max / equals
    [objectives]   minimise = [...], maximise = [...]
    [optimise]     objective, popsize, maxiter, seed, tol, held = {NAME = value} (for --optimise;
                   list variables not held stay at their first value)

Variable names are those of `study.variables.VARIABLES`; metric names those of
`study.records.METRICS` (inputs may be constrained too).
"""

from __future__ import annotations

import hashlib
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from settings import DEFAULT_MATERIALS, DEFAULT_STATION, LIMITS, RunConfig, cam_ids, known_cam_ids, registries
from study.samplers import SAMPLERS, SamplingSize
from study.variables import CAM, GEOMETRY_KEY, GEOMETRY_TARGETS, MATERIAL, STEP, VARIABLES

#: pipeline.py's part options, as keys of [fixed] (with a STEP geometry only)
PART_OPTIONS = ("bores", "pitch", "bore_radius", "body", "hardware_material", "hardware_from_step")
#: The first bytes of every STEP (ISO 10303-21) file.
STEP_HEADER = b"ISO-10303-21;"
TABLES = ("study", "variables", "fixed", "settings", "sampling", "constraints", "objectives", "optimise")


class StudyError(ValueError):
    """A study file (or option) that cannot be used; the one-line message names the key."""


@dataclass(frozen=True)
class Range:
    min: float
    max: float


@dataclass(frozen=True)
class Choices:
    values: tuple


@dataclass(frozen=True)
class PartFile:
    """A STEP file of the study, read and checked on the client: its bytes go with its FEA task."""

    name: str  # as written in the study file (the table's geometry_file)
    path: Path  # resolved against the study file's folder
    sha256: str
    data: bytes = field(repr=False)


@dataclass(frozen=True)
class Settings:
    """The run settings a study holds for every design point; the defaults are RunConfig's."""

    mesh_size_m: float | None = RunConfig.mesh_size_m  # finest FEA level; None: the pipeline's default levels
    order: int = RunConfig.order
    samples_per_degree: int = RunConfig.samples_per_degree
    solver: str = RunConfig.solver
    station: str = DEFAULT_STATION  # where the records' metrics are taken
    settling_band_m: float = RunConfig.settling_band_m
    steady_state: bool = RunConfig.steady_state
    drive: str | None = RunConfig.drive  # None: pipeline.py's default drive (RunConfig.machine_drive)
    fea_cache: bool = True  # each worker's own on-disk FEA cache (no shared disk needed)


@dataclass(frozen=True)
class Sampling:
    method: str = "grid"
    levels: int = 3
    points: int = 8
    seed: int = 0


@dataclass(frozen=True)
class Constraint:
    metric: str
    min: float | None = None
    max: float | None = None
    equals: object = None

    def violation(self, value) -> str | None:
        """Why `value` breaks the constraint, or None when it holds."""
        if value is None or (isinstance(value, float) and math.isnan(value)):
            return f"{self.metric} not computed"
        if self.equals is not None and value != self.equals:
            return f"{self.metric} = {value} (required {self.equals})"
        if self.min is not None and value < self.min:
            return f"{self.metric} = {value:.4g} < {self.min:g}"
        if self.max is not None and value > self.max:
            return f"{self.metric} = {value:.4g} > {self.max:g}"
        return None

    def amount(self, value) -> float:
        """How far `value` is outside the constraint, relative to its bound (0 when it holds)."""
        if self.violation(value) is None:
            return 0.0
        if value is None or isinstance(value, bool) or self.equals is not None or math.isnan(value):
            return 1.0
        bound = self.min if self.min is not None and value < self.min else self.max
        return abs(value - bound) / max(abs(bound), 1e-300)


@dataclass(frozen=True)
class Objective:
    metric: str
    sense: str  # "min" or "max"


@dataclass(frozen=True)
class OptimiseSpec:
    objective: str
    sense: str = "min"
    held: dict = field(default_factory=dict)  # list variables held at one value while optimising
    popsize: int = 5
    maxiter: int = 5
    seed: int = 0
    tol: float = 0.01


@dataclass(frozen=True)
class StudySpec:
    name: str
    variables: dict  # name -> Range | Choices, in file order (varied)
    fixed: dict  # name -> value (held)
    settings: Settings
    sampling: Sampling
    constraints: tuple[Constraint, ...]
    objectives: tuple[Objective, ...]
    optimise: OptimiseSpec | None
    report_best: int = 1
    parts: dict = field(default_factory=dict)  # geometry_file name -> PartFile
    part_options: dict = field(default_factory=dict)  # PART_OPTIONS given in [fixed]

    @property
    def ranges(self) -> dict[str, Range]:
        return {n: v for n, v in self.variables.items() if isinstance(v, Range)}

    @property
    def choices(self) -> dict[str, Choices]:
        return {n: v for n, v in self.variables.items() if isinstance(v, Choices)}


def load_study(path: Path) -> StudySpec:
    """Read and validate a study file."""
    try:
        data = tomllib.loads(Path(path).read_text())
    except OSError as e:
        raise StudyError(f"{path}: cannot read the study file ({e.strerror or e})") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise StudyError(f"{path}: not a valid TOML file ({e})") from None
    try:
        return parse_study(data, Path(path).resolve().parent)
    except StudyError as e:
        raise StudyError(f"{path}: {e}") from None


def parse_study(data: dict, base_dir: Path | None = None) -> StudySpec:
    """The spec of a parsed study file; STEP paths are read relative to `base_dir` (default: here)."""
    _only(data, TABLES, "")
    head = _table(data, "study")
    _only(head, ("name", "report_best"), "study.")
    settings = _settings(_table(data, "settings"))
    materials = _known_materials()
    variable_table, fixed_table = dict(_table(data, "variables")), dict(_table(data, "fixed"))
    options = {k: fixed_table.pop(k) for k in PART_OPTIONS if k in fixed_table}
    geometry = _geometry(variable_table, fixed_table, Path.cwd() if base_dir is None else base_dir)
    variables = {name: _variable(name, value, materials) for name, value in variable_table.items()}
    fixed = {name: _fixed(name, value, materials) for name, value in fixed_table.items()}
    both = [n for n in variables if n in fixed]
    if both:
        raise StudyError(f"fixed.{both[0]}: also in [variables]; expected a name in one table only")
    parts = {}
    if geometry is not None:
        table, parts = geometry
        (variables if table == "variables" else fixed)["geometry_file"] = (
            Choices(tuple(parts)) if table == "variables" else next(iter(parts))
        )
        _no_builtin_dimensions(variables, fixed)
    _check_part_options(options, bool(parts), materials)
    if options.get("hardware_from_step") and "hardware_mass_kg" in {*variables, *fixed}:
        raise StudyError(
            "fixed.hardware_from_step: the hardware mass comes from the STEP file's solids; expected "
            "no hardware_mass_kg in [variables] or [fixed] with it"
        )
    _check_tensioner(variables, fixed)
    _default_choices(variables, fixed)
    sampling = _sampling(_table(data, "sampling"), variables)
    metrics = _metric_names()
    constraints = tuple(_constraint(i, c, metrics) for i, c in enumerate(_list(data, "constraints")))
    objectives = _objectives(_table(data, "objectives"), metrics)
    optimise = _optimise(data.get("optimise"), objectives, metrics, variables)
    return StudySpec(
        name=str(head.get("name", "study")),
        variables=variables,
        fixed=fixed,
        settings=settings,
        sampling=sampling,
        constraints=constraints,
        objectives=objectives,
        optimise=optimise,
        report_best=_int(head.get("report_best", 1), "study.report_best", 0),
        parts=parts,
        part_options=options,
    )


def _geometry(variables: dict, fixed: dict, base_dir: Path) -> tuple[str, dict] | None:
    """("variables" or "fixed", {name: PartFile}) of the `geometry` key, every file checked here on
    the client (before any task is sent); None for the built-in link."""
    for table, where in ((variables, "variables"), (fixed, "fixed")):
        if "geometry_file" in table:  # the column's name; the file names the STEP file(s) `geometry`
            raise StudyError(
                f"{where}.geometry_file: the study file's key is {GEOMETRY_KEY!r}; expected "
                f'{GEOMETRY_KEY} = "link.step"'
            )
    if GEOMETRY_KEY in variables and GEOMETRY_KEY in fixed:
        raise StudyError(f"fixed.{GEOMETRY_KEY}: also in [variables]; expected a name in one table only")
    if GEOMETRY_KEY in fixed:
        value, where = fixed.pop(GEOMETRY_KEY), f"fixed.{GEOMETRY_KEY}"
        if not isinstance(value, str) or not value:
            raise StudyError(f"{where}: expected the path of a STEP file (relative to the study file), got {value!r}")
        return "fixed", {value: read_step_file(value, base_dir, where)}
    if GEOMETRY_KEY not in variables:
        return None
    value, where = variables.pop(GEOMETRY_KEY), f"variables.{GEOMETRY_KEY}"
    if not isinstance(value, list) or not value or not all(isinstance(v, str) and v for v in value):
        raise StudyError(
            f"{where}: expected a list of STEP file paths (CAD variants, relative to the study file), got {value!r}"
        )
    parts: dict[str, PartFile] = {}
    for i, name in enumerate(value):
        part = read_step_file(name, base_dir, f"{where}[{i}]")
        for other in parts.values():
            if other.path == part.path or other.sha256 == part.sha256:
                same = "the same file" if other.path == part.path else "files with the same contents"
                raise StudyError(f"{where}: {other.name!r} and {name!r} are {same}; expected each CAD variant once")
        parts[name] = part
    return "variables", parts


def read_step_file(name: str, base_dir: Path, key: str) -> PartFile:
    """The STEP file `name` (relative to the study file's folder), or a one-line StudyError."""
    path = (base_dir / name).resolve()
    if not path.exists():
        raise StudyError(
            f"{key}: no such file {name!r} (looked in {base_dir}); expected a STEP file of one link, "
            "its path relative to the study file"
        )
    if path.is_dir():
        raise StudyError(f"{key}: {name!r} is a folder; expected a STEP file of one link")
    try:
        data = path.read_bytes()
    except OSError as e:
        raise StudyError(f"{key}: cannot read {name!r} ({e.strerror or e}); expected a readable STEP file") from None
    if not data.lstrip().startswith(STEP_HEADER):
        raise StudyError(
            f"{key}: {name!r} is not a STEP file (it does not begin with "
            f"{STEP_HEADER.decode()}); expected a STEP file of one link (.step, .stp)"
        )
    return PartFile(name, path, hashlib.sha256(data).hexdigest(), data)


def _no_builtin_dimensions(variables: dict, fixed: dict) -> None:
    for table, where in ((variables, "variables"), (fixed, "fixed")):
        for name in table:
            if name in VARIABLES and VARIABLES[name].target in GEOMETRY_TARGETS:
                raise StudyError(
                    f"{where}.{name}: a dimension of the built-in link, and the study has a STEP "
                    f"{GEOMETRY_KEY}; expected one or the other (the file gives the link's shape)"
                )


def _check_part_options(options: dict, has_step: bool, materials: tuple[str, ...]) -> None:
    """pipeline.py's part options, checked by the same code as its command line."""
    if not options:
        return
    key = f"fixed.{next(iter(options))}"
    if not has_step:
        raise StudyError(
            f'{key}: a part option, only for a STEP {GEOMETRY_KEY}; expected {GEOMETRY_KEY} = "link.step" with it'
        )
    from geometry.errors import GeometryError

    for name in ("bores", "pitch", "bore_radius", "body"):
        if name in options and (isinstance(options[name], bool) or not isinstance(options[name], (str, int, float))):
            raise StudyError(f"fixed.{name}: expected a value as on pipeline.py's command line, got {options[name]!r}")
    try:
        part_source(Path("part.step"), options)
    except GeometryError as e:
        raise StudyError(f"fixed: {e}") from None
    if "hardware_from_step" in options and not isinstance(options["hardware_from_step"], bool):
        raise StudyError(f"fixed.hardware_from_step: expected true or false, got {options['hardware_from_step']!r}")
    if "hardware_material" in options:
        ids = options["hardware_material"]
        names = [s.strip() for s in ids.split(",")] if isinstance(ids, str) else []
        unknown = [n for n in names if n not in materials]
        if not names or unknown:
            raise StudyError(
                f"fixed.hardware_material: unknown material {(unknown or [ids])[0]!r}; expected one of "
                f"{', '.join(materials)} (or several, comma-separated, one per hardware solid)"
            )
    elif options.get("hardware_from_step"):
        raise StudyError("fixed.hardware_from_step: the hardware solids need a material; expected hardware_material")


def part_source(path: Path, options: dict):
    """geometry.assembly.LinkSource of a STEP path with the study's part options (pipeline.py's code)."""
    from argparse import Namespace

    from geometry.options import link_source

    given = {
        name: (None if name not in options else str(options[name]))
        for name in ("bores", "pitch", "bore_radius", "body")
    }
    return link_source(path, Namespace(**given))


def _check_tensioner(variables: dict, fixed: dict) -> None:
    """The idler tensioner's rate or damping needs its carriage mass (as on pipeline.py's command line)."""
    given = {n for n in (*variables, *fixed) if n.startswith("tensioner_")}
    if given and "tensioner_mass_kg" not in given:
        name = sorted(given)[0]
        where = "variables" if name in variables else "fixed"
        raise StudyError(
            f"{where}.{name}: the tensioner needs its carriage mass; expected tensioner_mass_kg in "
            "[fixed] or [variables]"
        )


def _only(table: dict, allowed: tuple, prefix: str) -> None:
    for key in table:
        if key not in allowed:
            raise StudyError(f"{prefix}{key}: unknown key; expected one of {', '.join(allowed)}")


def _table(data: dict, name: str) -> dict:
    value = data.get(name, {})
    if not isinstance(value, dict):
        raise StudyError(f"{name}: expected a table [{name}], got {type(value).__name__}")
    return value


def _list(data: dict, name: str) -> list:
    value = data.get(name, [])
    if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
        raise StudyError(f"{name}: expected an array of tables [[{name}]]")
    return value


def _known_materials() -> tuple[str, ...]:
    return registries.material_ids()


def _metric_names() -> tuple[str, ...]:
    from study.records import METRICS

    return tuple(METRICS) + tuple(VARIABLES)


def _number(value, key: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise StudyError(f"{key}: expected a finite number, got {value!r}")
    return float(value)


def _int(value, key: str, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise StudyError(f"{key}: expected a whole number >= {minimum}, got {value!r}")
    return value


def _check_value(name: str, value, key: str, materials: tuple[str, ...]):
    variable = VARIABLES[name]
    if variable.target == STEP:
        return value
    if variable.target == MATERIAL:
        if value not in materials:
            raise StudyError(f"{key}: unknown material {value!r}; expected one of {', '.join(materials)}")
        return value
    if variable.target == CAM:
        if value not in known_cam_ids():
            raise StudyError(f"{key}: unknown cam law {value!r}; expected one of {', '.join(known_cam_ids())} or 'all'")
        return value
    number = _number(value, key)
    if variable.kind is int and number != int(number):
        raise StudyError(f"{key}: expected a whole number, got {value!r}")
    if not variable.accepts(number):
        raise StudyError(f"{key}: expected a value {variable.expected()}, got {value!r}")
    return variable.kind(number)


def _known(name: str, key: str) -> None:
    if name not in VARIABLES:
        raise StudyError(f"{key}: unknown variable; expected one of {', '.join(VARIABLES)}")


def _variable(name: str, value, materials) -> Range | Choices:
    key = f"variables.{name}"
    _known(name, key)
    choice = VARIABLES[name].kind is str
    if value == "all" and VARIABLES[name].target == CAM:
        return Choices(cam_ids())
    if isinstance(value, list):
        if not value:
            raise StudyError(f"{key}: empty list; expected at least one value")
        values = tuple(_check_value(name, v, f"{key}[{i}]", materials) for i, v in enumerate(value))
        if len(set(values)) != len(values):
            raise StudyError(f"{key}: repeated value in the list {list(value)}")
        return Choices(values)
    if isinstance(value, dict) and not choice:
        _only(value, ("min", "max"), f"{key}.")
        if "min" not in value or "max" not in value:
            raise StudyError(f"{key}: a range needs both min and max, got {value}")
        low = _check_value(name, value["min"], f"{key}.min", materials)
        high = _check_value(name, value["max"], f"{key}.max", materials)
        if not low < high:
            raise StudyError(
                f"{key}: empty range, min {value['min']!r} >= max {value['max']!r}; "
                f"expected min < max (or a list, or [fixed] for one value)"
            )
        return Range(float(low), float(high))
    form = (
        "a list of names" + (" or 'all'" if VARIABLES[name].target == CAM else "")
        if choice
        else "{min = A, max = B} or a list of values"
    )
    raise StudyError(f"{key}: expected {form}, got {value!r}")


def _fixed(name: str, value, materials):
    key = f"fixed.{name}"
    _known(name, key)
    return _check_value(name, value, key, materials)


def _default_choices(variables: dict, fixed: dict) -> None:
    """Material and cam law default to RunConfig's: both materials, every cam law."""
    for name, default in (("material", DEFAULT_MATERIALS), ("cam", cam_ids())):
        if name not in variables and name not in fixed:
            variables[name] = Choices(tuple(default))


def _in_limits(table: dict, name: str) -> float:
    """A number of [settings] within the RunConfig field's LIMITS (SI, as the study file is)."""
    key = f"settings.{name}"
    value = _number(table[name], key)
    bounds = LIMITS[name].bounds
    if not bounds.accepts(value):
        raise StudyError(f"{key}: expected {LIMITS[name].what} {bounds.expected()}, got {table[name]!r}")
    return value


def _settings(table: dict) -> Settings:
    defaults = Settings()
    _only(table, tuple(Settings.__dataclass_fields__), "settings.")
    values = {}
    if "mesh_size_m" in table:
        values["mesh_size_m"] = _in_limits(table, "mesh_size_m")
    if "order" in table and table["order"] not in registries.ELEMENT_ORDERS:
        raise StudyError(
            f"settings.order: expected one of {', '.join(map(str, registries.ELEMENT_ORDERS))}, got {table['order']!r}"
        )
    if "samples_per_degree" in table:
        _int(table["samples_per_degree"], "settings.samples_per_degree", int(LIMITS["samples_per_degree"].bounds.lower))
    methods = registries.solver_methods()
    if "solver" in table and table["solver"] not in methods:
        raise StudyError(f"settings.solver: unknown method {table['solver']!r}; expected one of {', '.join(methods)}")
    stations = registries.station_names()
    if "station" in table and table["station"] not in stations:
        raise StudyError(f"settings.station: expected one of {', '.join(stations)}, got {table['station']!r}")
    if "settling_band_m" in table:
        _in_limits(table, "settling_band_m")
    drives = registries.drives()
    if "drive" in table and table["drive"] not in drives:
        raise StudyError(f"settings.drive: expected one of {', '.join(drives)}, got {table['drive']!r}")
    for flag in ("steady_state", "fea_cache"):
        if flag in table and not isinstance(table[flag], bool):
            raise StudyError(f"settings.{flag}: expected true or false, got {table[flag]!r}")
    for key in ("order", "samples_per_degree", "solver", "station", "steady_state", "drive", "fea_cache"):
        if key in table:
            values[key] = table[key]
    if "settling_band_m" in table:
        values["settling_band_m"] = float(table["settling_band_m"])
    return Settings(**{**defaults.__dict__, **values})


def _sampling(table: dict, variables: dict) -> Sampling:
    _only(table, ("method", "levels", "points", "seed"), "sampling.")
    default = Sampling()
    method = table.get("method", default.method)
    if method not in SAMPLERS:
        raise StudyError(f"sampling.method: expected one of {', '.join(SAMPLERS)}, got {method!r}")
    sampler = SAMPLERS[method]
    levels = _int(table.get("levels", default.levels), "sampling.levels", 2)
    points = _int(table.get("points", default.points), "sampling.points", 1)
    seed = _int(table.get("seed", default.seed), "sampling.seed", 0)
    has_range = any(isinstance(v, Range) for v in variables.values())
    if sampler.size_key == "points" and not has_range:
        raise StudyError(
            f"sampling.method: {method} samples ranges, and [variables] has none; "
            'expected a {min, max} range or method = "grid"'
        )
    other_key = "levels" if sampler.size_key == "points" else "points"
    if other_key in table:
        takers = ", ".join(name for name, s in SAMPLERS.items() if s.size_key == other_key)
        raise StudyError(f"sampling.{other_key}: only for {takers}; {method} takes {sampler.size_key}")
    problem = sampler.check(SamplingSize(levels, points, seed))
    if problem:
        raise StudyError(problem)
    return Sampling(method, levels, points, seed)


def _constraint(i: int, table: dict, metrics: tuple[str, ...]) -> Constraint:
    key = f"constraints[{i}]"
    _only(table, ("metric", "min", "max", "equals"), f"{key}.")
    metric = table.get("metric")
    if metric not in metrics:
        raise StudyError(f"{key}.metric: unknown metric {metric!r}; expected one of {', '.join(metrics)}")
    bounds = {b: _number(table[b], f"{key}.{b}") for b in ("min", "max") if b in table}
    if not bounds and "equals" not in table:
        raise StudyError(f"{key}: expected min, max or equals for {metric}")
    return Constraint(metric, bounds.get("min"), bounds.get("max"), table.get("equals"))


def _objectives(table: dict, metrics: tuple[str, ...]) -> tuple[Objective, ...]:
    _only(table, ("minimise", "maximise"), "objectives.")
    out = []
    for sense_key, sense in (("minimise", "min"), ("maximise", "max")):
        names = table.get(sense_key, [])
        if not isinstance(names, list):
            raise StudyError(f"objectives.{sense_key}: expected a list of metric names, got {names!r}")
        for name in names:
            if name not in metrics:
                raise StudyError(
                    f"objectives.{sense_key}: unknown metric {name!r}; expected one of {', '.join(metrics)}"
                )
            out.append(Objective(name, sense))
    return tuple(out)


def _optimise(table, objectives, metrics, variables: dict) -> OptimiseSpec | None:
    if table is None:
        return None
    if not isinstance(table, dict):
        raise StudyError("optimise: expected a table [optimise]")
    _only(table, ("objective", "popsize", "maxiter", "seed", "tol", "held"), "optimise.")
    objective = table.get("objective", objectives[0].metric if objectives else None)
    if objective not in metrics:
        raise StudyError(f"optimise.objective: unknown metric {objective!r}; expected one of {', '.join(metrics)}")
    sense = next((o.sense for o in objectives if o.metric == objective), "min")
    tol = _number(table.get("tol", 0.01), "optimise.tol")
    held = table.get("held", {})
    if not isinstance(held, dict):
        raise StudyError(f"optimise.held: expected a table of list variables and one value each, got {held!r}")
    held = {("geometry_file" if k == GEOMETRY_KEY else k): v for k, v in held.items()}
    for name, value in held.items():
        if not isinstance(variables.get(name), Choices) or value not in variables[name].values:
            raise StudyError(
                f"optimise.held.{name}: expected a variable listed in [variables] and one of its values, got {value!r}"
            )
    return OptimiseSpec(
        objective,
        sense,
        dict(held),
        _int(table.get("popsize", 5), "optimise.popsize", 2),
        _int(table.get("maxiter", 5), "optimise.maxiter", 1),
        _int(table.get("seed", 0), "optimise.seed", 0),
        tol,
    )
