"""What a user asks of one optimisation: one frozen record, made once, passed whole.

:class:`OptimizeOptions` is built once, by the command line (``warpskill.cli.common.optimize_options``)
or by the API (:func:`warpskill.optimize`'s keywords), and travels unchanged through
:func:`~warpskill.optimizer.optimize_many`, the Ray tasks (pickled as it is), the
benchmarks and ``warpskill run``; it is saved with the reconstruction
(:meth:`to_json`), so a result says how it was made.

Any field, including those of the nested :class:`OptimizeConfig`, :class:`LossWeights`
and :class:`~warpskill.engine.simulation.PhysicsConfig`, can be set by a dotted path
(:meth:`with_settings`, the CLI's ``--set config.iterations=300``).
"""

from __future__ import annotations

import dataclasses
import json
import typing
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

from warpskill.optimizer.config import OptimizeConfig
from warpskill.optimizer.known import check_known


@dataclass(frozen=True)
class OptimizeOptions:
    """Everything that decides a reconstruction besides the demonstration itself.

    Attributes:
        device: torch/Warp device (``"cpu"``, ``"cuda"``, ``"cuda:1"``); None: the CPU.
        seed: seed of torch's generator (on the CPU results repeat exactly per seed; CUDA's atomic sums
            vary in order, so runs there differ slightly).
        init_only: stop after stage (a) (the paper's "initialisation only" ablation).
        known: lengths known in advance [m] as sorted ``(name, metres)`` pairs, which fix
            the scene's scale; names in :data:`warpskill.optimizer.known.KNOWN_LENGTHS`.
            A mapping is accepted and normalised.
        object_noun: what the manipulated object is (e.g. ``"mug"``), replacing the
            demonstration's ``object_noun``; where no length is ``known``, its typical size
            (:func:`warpskill.nouns.typical.typical_size`) is a weak prior on the object's
            largest edge. A noun without a typical size adds no prior (one line says so).
        config: iterations, learning rates, resolution, loss weights, physics constants.
    """

    device: str | None = None
    seed: int = 0
    init_only: bool = False
    known: tuple[tuple[str, float], ...] = ()
    object_noun: str | None = None
    config: OptimizeConfig = field(default_factory=OptimizeConfig)

    def __post_init__(self) -> None:
        known = self.known if isinstance(self.known, Mapping) else dict(self.known or ())
        object.__setattr__(self, "known", tuple(sorted(check_known(known).items())))
        object.__setattr__(self, "seed", int(self.seed))
        object.__setattr__(self, "init_only", bool(self.init_only))
        if self.device is not None:
            object.__setattr__(self, "device", str(self.device))
        if self.object_noun is not None and not isinstance(self.object_noun, str):
            raise TypeError(f"object_noun must be a string, got {type(self.object_noun).__name__}")
        if not isinstance(self.config, OptimizeConfig):
            raise TypeError(f"config must be an OptimizeConfig, got {type(self.config).__name__}")

    @property
    def known_lengths(self) -> dict[str, float]:
        """``known`` as a dict (name -> metres)."""
        return dict(self.known)

    @classmethod
    def build(cls, options: "OptimizeOptions | None" = None, **fields) -> "OptimizeOptions":
        """``options`` (default: all defaults) with ``fields`` replaced; ``iterations=N`` sets
        ``config.iterations`` (None leaves it). Unknown names raise TypeError naming them."""
        options = options or cls()
        iterations = fields.pop("iterations", None)
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(fields) - names)
        if unknown:
            raise TypeError(f"unknown optimisation option(s): {', '.join(unknown)}; options: "
                            f"{', '.join(sorted(names | {'iterations'}))}")
        options = replace(options, **fields)
        if iterations is not None:
            options = replace(options, config=replace(options.config, iterations=int(iterations)))
        return options

    def with_settings(self, settings: Sequence[str]) -> "OptimizeOptions":
        """These options with ``"dotted.path=value"`` settings applied, e.g.
        ``config.iterations=300`` or ``config.weights.grasp_margin=0.01``.

        Raises:
            ValueError: naming the setting, for a malformed one, an unknown path or a value
                that does not parse as the field's type.
        """
        options = self
        for setting in settings:
            path, sep, text = setting.partition("=")
            if not sep or not path.strip():
                raise ValueError(f"--set expects PATH=VALUE (e.g. config.iterations=300), got {setting!r}")
            options = _set_path(options, path.strip().split("."), text.strip(), setting)
        return options

    def to_json(self) -> str:
        """The options as JSON (nested records as objects), as saved with a reconstruction."""
        return json.dumps(dataclasses.asdict(self), sort_keys=True)

    @classmethod
    def from_json(cls, text: str) -> "OptimizeOptions":
        """Options back from :meth:`to_json`."""
        return _from_plain(cls, json.loads(text))


def _set_path(record, path: list[str], text: str, setting: str):
    """``record`` with the field at ``path`` set to ``text`` parsed as that field's type."""
    fields = {f.name: f for f in dataclasses.fields(record)}
    name = path[0]
    if name not in fields:
        where = type(record).__name__
        raise ValueError(f"--set {setting!r}: {where} has no field {name!r}; fields: {', '.join(fields)}")
    current = getattr(record, name)
    if len(path) > 1:
        if not dataclasses.is_dataclass(current):
            raise ValueError(f"--set {setting!r}: {name!r} is a value, not a group of settings")
        return replace(record, **{name: _set_path(current, path[1:], text, setting)})
    if dataclasses.is_dataclass(current):
        raise ValueError(f"--set {setting!r}: {name!r} is a group; set one of its fields, e.g. {name}.<field>")
    return replace(record, **{name: _parse_value(text, current, setting)})


def _parse_value(text: str, current, setting: str):
    """``text`` as a value of ``current``'s type (JSON for tuples and None)."""
    try:
        if isinstance(current, bool):
            if text.lower() not in ("true", "false", "1", "0"):
                raise ValueError(text)
            return text.lower() in ("true", "1")
        if isinstance(current, int):
            return int(text)
        if isinstance(current, float):
            return float(text)
        if isinstance(current, str) or current is None:
            return None if text.lower() in ("none", "null") else text
        return _as_tuples(json.loads(text))
    except ValueError:
        raise ValueError(f"--set {setting!r}: {text!r} is not a valid {type(current).__name__}") from None


def _as_tuples(value):
    """JSON lists as (nested) tuples, as the frozen records keep them."""
    return tuple(_as_tuples(v) for v in value) if isinstance(value, list) else value


def _from_plain(cls, data: dict):
    """A (nested) dataclass from :func:`dataclasses.asdict` output."""
    hints = typing.get_type_hints(cls)
    values = {}
    for f in dataclasses.fields(cls):
        if f.name not in data:
            continue
        kind = hints[f.name]
        value = data[f.name]
        values[f.name] = _from_plain(kind, value) if dataclasses.is_dataclass(kind) else _as_tuples(value)
    return cls(**values)
