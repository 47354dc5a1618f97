"""A sweep's specification (``kinegrasp sweep SPEC``): the grid read from YAML or JSON, every
entry checked before any work starts (:class:`SweepSpec`; one :class:`SpecError` line naming the
first bad entry), and its tasks (:class:`SweepTask`: one chunk of one cell).

The grid is objects x grasps x sigmas x noise types x engines; each cell is ``samples``
draws split into chunks of ``chunk``. A ``noise`` entry may also be a noise model (a spec
mapping or file: :mod:`kinegrasp_env.montecarlo.sweep_noise`), whose joint sigma is the cell's
sigma.

Grasps: an object's come from the robot's shipped set (``assets/grasps/<robot>/``);
``grasp_files`` maps an object to a grasp file (``kinegrasp plan``'s output, relative to the
spec file) whose grasps replace the shipped set, which is how an imported object (it has
none) is swept. ``grasps`` indexes
each object's set; each grasp file's SHA-256 is kept with the spec
(:meth:`SweepSpec.sources`).

Robot: ``robot`` (default: the robot of the ``grasp_files``' grasps, else ``kuka_sdh``;
``kinegrasp sweep --robot`` overrides it) names the catalog robot. Its grasps come from its
shipped sets or from ``grasp_files`` (every grasp of a file must be a grasp of that robot).
Its draws are joint noise on its arm joints (a distribution entry of ``noise``) or a noise
model of the sources its engines take, closed by its own engines
(:func:`kinegrasp_env.montecarlo.sweep.run_task`).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from kinegrasp_env.montecarlo.grasp_stats import ENGINES, chunk_sizes
from kinegrasp_env.montecarlo.sweep_grasps import (
    SpecError,
    check_grasp_indices,
    check_grasp_sets,
    files_robot,
    grasp_files,
    grasp_set,
)
from kinegrasp_env.montecarlo.sweep_noise import noise_entries
from kinegrasp_env.robot.catalog import DEFAULT_ROBOT
from kinegrasp_env.sampling.noise import check_sigma_bound
from kinegrasp_env.sampling.noise_model import NoiseModel
from kinegrasp_env.sampling.noise_spec import noise_model_from_spec
from kinegrasp_env.spec_yaml import read_spec
from kinegrasp_env.world.grasps import Grasp
from kinegrasp_env.world.objects import object_names, object_version

SPEC_KEYS = ("objects", "grasps", "grasp_files", "sigmas", "noise", "engines", "samples",
             "chunk", "seed", "robot", "friction")


@dataclass(frozen=True)
class SweepSpec:
    """A validated sweep grid (see the module docstring)."""

    objects: tuple[str, ...]
    grasps: tuple[int, ...] | None  # None: every shipped grasp
    sigmas: tuple[float, ...]
    noise: tuple[str, ...] = ("gaussian",)
    engines: tuple[str, ...] = ("pybullet",)
    samples: int = 1000
    chunk: int = 250
    seed: int = 0
    #: (label, spec JSON) of the noise models among ``noise``
    models: tuple[tuple[str, str], ...] = ()
    #: (object, absolute path, SHA-256) of each grasp file replacing a shipped set
    grasp_files: tuple[tuple[str, str, str], ...] = ()
    #: the catalog robot whose grasps are swept
    robot: str = DEFAULT_ROBOT
    #: the contacts' friction coefficient mu in every cell
    friction: float = 0.5

    def __post_init__(self) -> None:
        if "physics" in self.engines:
            from kinegrasp_env.physics.protocol import check_simulated_friction

            try:
                check_simulated_friction(self.friction)
            except ValueError:
                raise SpecError(f"friction {self.friction:g}: the physics engine's cells need "
                                "a friction > 0 (a simulated grip at mu 0 cannot hold)"
                                ) from None

    @classmethod
    def from_dict(cls, data: Any, where: str = "spec", base: str | Path | None = None,
                  robot: str | None = None) -> SweepSpec:
        """Validate every entry; one :class:`SpecError` naming the first bad one (``base``:
        the folder noise spec files are relative to; ``robot``: replaces the spec's
        ``robot``, as ``--robot`` does)."""
        if not isinstance(data, dict):
            raise SpecError(f"{where}: expected a mapping of {', '.join(SPEC_KEYS)}")
        unknown = sorted(set(data) - set(SPEC_KEYS))
        if unknown:
            raise SpecError(f"{where}: unknown key {unknown[0]!r}; allowed keys: "
                            f"{', '.join(SPEC_KEYS)}")
        for key in ("objects", "sigmas"):
            if key not in data:
                raise SpecError(f"{where}: missing key {key!r}")
        objects = _names(data["objects"], object_names(), "objects", where)
        if robot is None:  # the spec's, else its swept objects' grasp files' (read only then)
            robot = _robot(data["robot"] if "robot" in data
                           else files_robot(data.get("grasp_files"), base, objects), where)
        else:
            robot = _robot(robot, "--robot")
        files = grasp_files(data.get("grasp_files", {}), objects, where, base, robot)
        check_grasp_sets(objects, files, where, robot)
        noise, models = _noise(data.get("noise", ["gaussian"]), where, base)
        engines = _names(data.get("engines", ["pybullet"]), ENGINES, "engines", where)
        _check_robot_cells(robot, models, engines, where)
        sigmas = _unique(tuple(_sigma(s, where) for s in _list(data["sigmas"], "sigmas", where)),
                         "sigmas", where)
        grasps = data.get("grasps", "all")
        if grasps == "all":
            indices = None
        else:
            try:
                given = tuple(_integer(g, "grasps", where, low=0)
                              for g in _list(grasps, "grasps", where))
            except SpecError:
                raise SpecError(f"{where}: 'grasps' must be \"all\" or a list of grasp indices "
                                f"(integers >= 0), got {grasps!r}") from None
            indices = _unique(given, "grasps", where)
            check_grasp_indices(objects, indices, files, where, robot)
        samples = _integer(data.get("samples", 1000), "samples", where, low=1)
        chunk = _integer(data.get("chunk", 250), "chunk", where, low=1)
        seed = _integer(data.get("seed", 0), "seed", where, low=0)
        friction = _friction(data.get("friction", 0.5), where)
        spec = cls(objects, indices, sigmas, noise, engines, samples, chunk, seed, models,
                   files, robot, friction)
        drawn = spec.friction_sources()
        if "friction" in data and drawn:
            raise SpecError(f"{where}: friction and the friction source of noise "
                            f"{drawn[0][0]!r} both set mu: the source draws mu per draw; give "
                            "one of them")
        return spec

    def friction_sources(self) -> list[tuple[str, NoiseModel]]:
        """(label, model) of the noise models among ``noise`` that draw mu per draw (a
        friction source), whose cells take no fixed ``friction``."""
        models = [(label, noise_model_from_spec(json.loads(text)))
                  for label, text in self.models]
        return [(label, model) for label, model in models if model.friction is not None]

    @classmethod
    def from_file(cls, path: str | Path, robot: str | None = None) -> SweepSpec:
        """Read a YAML (or JSON) spec file (numbers as YAML 1.2 reads them: ``1e-2`` is a
        number); a syntax error is one :class:`SpecError` line: file, line, column, what.
        ``robot``: replaces the spec's (``--robot``)."""
        path = Path(path)
        try:
            data = read_spec(path)
        except ValueError as exc:
            raise SpecError(str(exc)) from None
        return cls.from_dict(data, where=str(path), base=path.parent, robot=robot)

    def grasp_set(self, object_name: str) -> tuple[Grasp, ...]:
        """The grasps of ``object_name`` the sweep indexes: its grasp file's, else its
        shipped set."""
        return grasp_set(object_name, self.grasp_files, self.robot)

    def grasp(self, object_name: str, index: int) -> Grasp:
        return self.grasp_set(object_name)[index]

    def grasp_indices(self, object_name: str) -> tuple[int, ...]:
        if self.grasps is None:
            return tuple(range(len(self.grasp_set(object_name))))
        return self.grasps

    def sources(self) -> dict[str, str]:
        """What the store must have been made with besides the streams: per object, its
        grasp file's SHA-256 (or ``shipped``) and its catalog version (the robot is
        checked with the streams: :class:`~kinegrasp_env.montecarlo.sweep.SweepStore`)."""
        files = {name: digest for name, _, digest in self.grasp_files}
        out = {}
        for name in self.objects:
            out[f"grasps:{name}"] = files.get(name, "shipped")
            out[f"object:{name}"] = object_version(name)
        return out

    def cells(self) -> list[tuple[str, int, float, str, str]]:
        """(object, grasp, sigma, noise, engine) in a fixed order."""
        return [(o, g, s, n, e) for o in self.objects for g in self.grasp_indices(o)
                for s in self.sigmas for n in self.noise for e in self.engines]

    def tasks(self) -> list[SweepTask]:
        """Every task, carrying its grasp's q0 (a worker needs no grasp file)."""
        sizes = chunk_sizes(self.samples, self.chunk)
        models = dict(self.models)
        return [SweepTask(o, g, s, n, e, c, size, self.seed, models.get(n),
                          tuple(self.grasp(o, g).q0.tolist()), self.robot, c * self.chunk,
                          self.friction)
                for (o, g, s, n, e) in self.cells() for c, size in enumerate(sizes)]


def _robot(value: Any, where: str) -> str:
    """A catalog robot's name; else one :class:`SpecError` line listing the known ones."""
    from kinegrasp_env.robot.catalog import check_robot_name
    from kinegrasp_env.robot.description import RobotDescriptionError

    try:
        return check_robot_name(value)
    except RobotDescriptionError as exc:
        raise SpecError(f"{where}: {exc}" if where == "--robot" else f"{where}: robot: {exc}"
                        ) from None


def _check_robot_cells(robot: str, models: tuple, engines: tuple[str, ...],
                       where: str) -> None:
    """What a description robot's engines take: its engines, and noise models of its sources
    (:func:`~kinegrasp_env.montecarlo.noise_rows.check_robot_noise`, every engine of the
    spec); one line naming what is not."""
    from kinegrasp_env.montecarlo.evaluate import ENGINES as ROBOT_ENGINES
    from kinegrasp_env.montecarlo.noise_rows import check_robot_noise
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.sampling.noise_spec import noise_model_from_spec

    arm = load_robot(robot).arm_dof
    for label, spec in models:
        for engine in engines:
            try:
                check_robot_noise(noise_model_from_spec(json.loads(spec)), robot, arm, engine)
            except ValueError as exc:
                raise SpecError(f"{where}: noise {label!r}: {exc}") from None
    bad = [e for e in engines if e not in ROBOT_ENGINES]
    if bad:
        raise SpecError(f"{where}: engines: {bad[0]!r} is not available for robot {robot!r} "
                        f"(its engines: {', '.join(ROBOT_ENGINES)})")


def _noise(value: Any, where: str, base: str | Path | None
           ) -> tuple[tuple[str, ...], tuple[tuple[str, str], ...]]:
    """``noise``: distribution names and noise models (labels, models)."""
    from kinegrasp_env.sampling.noise_model import NoiseSpecError

    try:
        labels, models = noise_entries(_list(value, "noise", where), base)
    except NoiseSpecError as exc:
        raise SpecError(f"{where}: noise: {exc}") from None
    return _unique(labels, "noise", where), models


#: Numbers YAML 1.1 reads as strings but YAML 1.2 (and every reader of the spec) as floats:
#: an exponent without a decimal point or without a sign (``1e-2``, ``5E3``, ``1.5e3``).


def _unique(values: tuple, key: str, where: str) -> tuple:
    """``values`` if no entry repeats; else a :class:`SpecError` naming the first repeat."""
    for i, value in enumerate(values):
        if value in values[:i]:
            raise SpecError(f"{where}: {value!r} appears twice in {key!r}; list each "
                            "entry once")
    return values


def _list(value: Any, key: str, where: str) -> list:
    values = list(value) if isinstance(value, (list, tuple)) else [value]
    if not values:
        raise SpecError(f"{where}: {key!r} is empty")
    return values


def _names(value: Any, known: tuple[str, ...], key: str, where: str) -> tuple[str, ...]:
    names = _list(value, key, where)
    for name in names:
        if name not in known:
            raise SpecError(f"{where}: unknown {key[:-1] if key.endswith('s') else key} "
                            f"{name!r} in {key!r}; known: {', '.join(known)}")
    return _unique(tuple(names), key, where)


def _sigma(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SpecError(f"{where}: sigma {value!r} is not a number")
    if not math.isfinite(value) or value < 0:
        raise SpecError(f"{where}: sigma must be finite and >= 0, got {value}")
    try:
        check_sigma_bound(value)
    except ValueError as exc:
        raise SpecError(f"{where}: {exc}") from None
    return float(value)


def _friction(value: Any, where: str) -> float:
    """``friction``: a number mu >= 0 (:func:`~kinegrasp_env.quality.wrenches.
    check_parameters`' rule)."""
    from kinegrasp_env.quality.wrenches import DEFAULT_NUM_EDGES, check_parameters

    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SpecError(f"{where}: friction {value!r} is not a number")
    try:
        return check_parameters(value, DEFAULT_NUM_EDGES)[0]
    except ValueError as exc:
        raise SpecError(f"{where}: {exc}") from None


def _integer(value: Any, key: str, where: str, low: int) -> int:
    """An integer >= ``low``; a float with no fractional part counts (``samples: 1e4``)."""
    if isinstance(value, float) and value.is_integer():
        value = int(value)
    if isinstance(value, bool) or not isinstance(value, int) or value < low:
        raise SpecError(f"{where}: {key!r} must be an integer >= {low}, got {value!r}")
    return value


@dataclass(frozen=True)
class SweepTask:
    """One chunk of one cell; ``key`` is its identity in the store."""

    object: str
    grasp: int
    sigma: float
    noise: str
    engine: str
    chunk: int
    size: int
    seed: int
    model: str | None = None  # the spec JSON of a noise-model cell
    q0: tuple[float, ...] | None = None  # the grasp's (dof,); None: shipped grasp ``grasp``
    robot: str = DEFAULT_ROBOT
    #: the chunk's first row within its cell's run (:meth:`SweepSpec.tasks` sets it: the
    #: chunk's index times the spec's chunk)
    offset: int = 0
    #: the contacts' friction coefficient mu
    friction: float = 0.5

    @property
    def key(self) -> str:
        head = "" if self.robot == DEFAULT_ROBOT else f"{self.robot}/"
        return (f"{head}{self.object}/{self.grasp}/{self.sigma!r}/{self.noise}/{self.engine}/"
                f"{self.chunk}")
