"""Values written on the command line, read one way: ``name=value`` assignments (scene parameters,
``--start``, ``--vary``) and comma-separated lists (``--grad``, ``--fit``, the benchmark's choices).

Every function raises ``UsageError`` with one line naming what was wrong.
"""

import math
from collections.abc import Iterable, Iterator, Mapping, Sequence

import jaxmpm as jm

from ._common import UsageError


def split(items: Iterable[str], expected: str, where: str = "") -> Iterator[tuple[str, str]]:
    """``name=value`` items as ``(name, value)`` pairs, split at the first ``=``, one at a time (so
    that the first bad item is the one reported, whatever is wrong with it).

    A name given twice is refused, not taken last-wins, for every command that reads assignments.

    Args:
        items: the items, e.g. ``["beta=400", "cells=3"]``.
        expected: the form the items take, for the error (e.g. ``"scene parameters are name=value"``).
        where: what the error starts with, e.g. ``"--start: "`` (nothing for scene parameters).

    Yields:
        ``(name, value)``, in order, ``value`` unparsed.

    Raises:
        UsageError: an item without ``=`` or without a name: ``"{expected}, got {item!r}"``; a name
            given twice: ``"{where}{name} is given twice: {first!r} and {second!r}"``.
    """
    seen: dict[str, str] = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not name:
            raise UsageError(f"{expected}, got {item!r}")
        if name in seen:
            raise UsageError(f"{where}{name} is given twice: {seen[name]!r} and {item!r}")
        seen[name] = item
        yield name, value


def names(items: Iterable[str]) -> list[str]:
    """The names of ``name=value`` items, for commands that check one option's names against another's
    (an item without ``=`` is left to ``split`` to report).

    Args:
        items: the items, e.g. ``["beta=400", "cells=3"]``.

    Returns:
        The names, in order.
    """
    return [item.partition("=")[0] for item in items if "=" in item]


ALIASES = {"detonation": {"smooth": "smooth_burn"}}
"""Command-line names of scene parameters whose field has another name: the detonation's ``smooth``
(whether its burn's ramp is C1) is ``smooth_burn``, because ``scene.smooth`` marks the particles away
from its front."""


def scene(name: str, items: Sequence[str], options: Mapping[str, bool] | None = None) -> jm.AbstractScene:
    """The scene ``name`` with the parameters ``items`` (``name=value``), each read as the type of its
    default: a string, a boolean (``true``/``false``, ``1``/``0``), an integer or a finite number.

    Args:
        name: a scene name (a key of ``jaxmpm.SCENES``).
        items: its parameters, e.g. ``["beta=400", "full=true"]``.
        options: the command's own options (argparse's names, e.g. ``steps`` for ``--steps``, each
            with whether it takes a value; ``_common.flags``): an unknown parameter that is one of
            them is refused with the option spelled out (``steps=125`` is ``--steps 125``,
            ``json=1`` is ``--json``).

    Returns:
        The scene.

    Raises:
        UsageError: an unknown scene or parameter, a value of the wrong type, a value the scene
            rejects, or a parameter the scene's run does not read (``jaxmpm.calibrate.unused``; but
            ``REPORTED``).
    """
    kwargs, spelled = _arguments(name, items, options)
    try:
        built = jm.SCENES[name](**kwargs)
    except ValueError as e:
        raise UsageError(str(e)) from None
    idle = jm.calibrate.unused(built)
    for key in kwargs:
        if key in idle and key not in REPORTED:
            raise UsageError(f"{spelled[key]} would do nothing: {idle[key]}; leave it out")
    return built


REPORTED = ("sqrt_2E",)
"""Scene parameters that the scene's run does not read (``jaxmpm.calibrate.unused``) but the commands
report with: the Gurney scenes' constant of Gurney's formula (``gurney_velocity``). Every other such
parameter is refused where a command is given it."""


def scene_arguments(name: str, items: Sequence[str], options: Mapping[str, bool] | None = None) -> dict:
    """The keyword arguments of ``scene`` (the items read as their defaults' types), without making the
    scene: this touches no JAX device, so a command that joins other processes first
    (``--distributed``) refuses a misspelt or mistyped parameter before it waits on them.

    Args:
        name: as for ``scene``.
        items: as for ``scene``.
        options: as for ``scene``.

    Returns:
        The scene's keyword arguments.

    Raises:
        UsageError: an unknown scene or parameter, or a value of the wrong type.
    """
    return _arguments(name, items, options)[0]


def _arguments(name: str, items: Sequence[str], options: Mapping[str, bool] | None) -> tuple[dict, dict]:
    """``scene_arguments``, and each parameter's ``name=value`` as given (for the messages)."""
    if name not in jm.SCENES:
        raise UsageError(f"unknown scene {name!r}; allowed: {', '.join(sorted(jm.SCENES))}")
    cls = jm.SCENES[name]
    defaults = cls.parameters()
    aliases = ALIASES.get(name, {})
    kwargs, spelled = {}, {}
    for given, raw in split(items, "scene parameters are name=value"):
        key = aliases.get(given, given)
        if key not in defaults:
            hint, option = "", given.replace("-", "_")
            if options and option in options:
                spelled_out = f"--{given.replace('_', '-')}" + (f" {raw}" if options[option] else "")
                hint = f" ({given} is an option of the command: {spelled_out})"
            raise UsageError(
                f"unknown parameter {key!r} for scene {name}; allowed: {', '.join(defaults)}{hint}"
            )
        if key in kwargs:  # the same parameter under another of its names
            raise UsageError(f"{key} is given twice: {spelled[key]!r} and {given + '=' + raw!r}")
        kwargs[key], spelled[key] = _typed(given, raw, defaults[key]), f"{given}={raw}"
    return kwargs, spelled


def _typed(key: str, raw: str, default):
    if isinstance(default, str):
        return raw
    if isinstance(default, bool):
        if raw.lower() not in ("true", "false", "1", "0"):
            raise UsageError(f"{key} must be true or false, got {raw!r}")
        return raw.lower() in ("true", "1")
    if isinstance(default, int):
        try:
            return int(raw)
        except ValueError:
            raise UsageError(f"{key} must be an integer, got {raw!r}") from None
    try:
        value = float(raw)
    except ValueError:
        raise UsageError(f"{key} must be a number, got {raw!r}") from None
    if not math.isfinite(value):
        raise UsageError(f"{key} must be finite, got {raw}")
    return value


def numbers(text: str, option: str) -> dict[str, float]:
    """``NAME=VALUE[,NAME=VALUE...]`` as a dict of floats (``--start``).

    Args:
        text: e.g. ``"gamma=1.4,P0=3e5"``.
        option: the option, for the error (``"--start"``).

    Returns:
        ``{name: value}``.

    Raises:
        UsageError: an item that is not ``NAME=VALUE`` with a finite number for ``VALUE``, or a name
            given twice.
    """
    expected = f"{option} takes NAME=VALUE[,NAME=VALUE...]"
    if not text.strip():  # an empty --start= would be read as no start values at all
        raise UsageError(f"{expected}, got an empty value")
    out = {}
    for key, raw in split(comma_list(text, option), expected, f"{option}: "):
        try:
            out[key] = float(raw)
        except ValueError:
            raise UsageError(f"{expected}, got {key + '=' + raw!r}") from None
        if not math.isfinite(out[key]):
            raise UsageError(f"{option}: {key} must be finite, got {raw}")
    return out


def ranges(items: Iterable[str], allowed: Sequence[str]) -> dict[str, tuple[float, float]]:
    """``NAME=LOW:HIGH`` items as ``{name: (low, high)}`` (``--vary``, repeatable).

    Args:
        items: e.g. ``["gamma=1.3:1.5", "P0=2e5:4e5"]``.
        allowed: the names that may vary.

    Returns:
        The ranges, finite with ``low <= high``.

    Raises:
        UsageError: an item not of the form ``NAME=LOW:HIGH``, a name not in ``allowed`` or given
            twice, bounds that are not numbers, not finite, or in the wrong order.
    """
    expected = "--vary takes NAME=LOW:HIGH"
    out = {}
    for key, raw in split(items, expected, "--vary: "):
        item = f"{key}={raw}"
        lo, sep, hi = raw.partition(":")
        if not sep:
            raise UsageError(f"{expected}, got {item!r}")
        if key not in allowed:
            raise UsageError(
                f"--vary: {key!r} is not a continuous scene parameter; allowed: {', '.join(allowed)}"
            )
        try:
            out[key] = (float(lo), float(hi))
        except ValueError:
            raise UsageError(f"--vary: LOW and HIGH must be numbers, got {item!r}") from None
        if not all(math.isfinite(v) for v in out[key]) or out[key][0] > out[key][1]:
            raise UsageError(f"--vary: need finite LOW <= HIGH, got {item!r}")
    return out


def comma_list(text: str, option: str | None = None) -> list[str]:
    """The items of a comma-separated list, as written (``--grad``, ``--fit``, ``--start``).

    Args:
        text: e.g. ``"beta,h"``.
        option: the option, for the error (``"--fit"``).

    Returns:
        The items, in order (none for a text of commas alone, which the caller refuses by its own
        words).

    Raises:
        UsageError: an item given twice: ``"{option}: {item} is given twice"``; an empty item beside
            others (``"gamma,"``).
    """
    items = [item for item in text.split(",") if item]
    if items and len(items) != len(text.split(",")):
        raise UsageError(f"{option + ': ' if option else ''}an empty item in {text!r} (a comma too many?)")
    for i, item in enumerate(items):
        if item in items[:i]:
            raise UsageError(f"{option + ': ' if option else ''}{item} is given twice")
    return items


def choices(text: str, option: str, allowed: Sequence[str]) -> list[str]:
    """A comma-separated list of choices, spaces around each stripped (the benchmark's options).

    Args:
        text: e.g. ``"numpy,jaxmpm"``.
        option: the option, for the error (``"--codes"``).
        allowed: the choices.

    Returns:
        The chosen items, in order.

    Raises:
        UsageError: an empty list or an item not in ``allowed``.
    """
    items = [t.strip() for t in text.split(",") if t.strip()]
    if not items or any(t not in allowed for t in items):
        raise UsageError(f"{option} must be a comma-separated list among {', '.join(allowed)}; got {text!r}")
    return items


def viscosity(text: str | None, scene: jm.AbstractScene | None = None) -> jm.ArtificialViscosity | None:
    """``--viscosity QUAD,LIN[,SHEAR]`` as the artificial viscosity (``None``: none).

    Args:
        text: the option's value, e.g. ``"2.0,0.2"`` or ``"2.0,0.2,0.5"``, or ``None`` when not given.
        scene: the scene it is for: a 1D one refuses ``SHEAR`` (a shear viscosity vanishes in 1D).

    Returns:
        The ``ArtificialViscosity``, or ``None``.

    Raises:
        UsageError: not two or three numbers >= 0, or three for a 1D scene.
    """
    if text is None:
        return None
    allowed = "--viscosity must be QUAD,LIN or QUAD,LIN,SHEAR (numbers >= 0)"
    items = text.split(",")
    if len(items) not in (2, 3):
        raise UsageError(f"{allowed}, got {text!r} ({len(items)} number{'s' if len(items) > 1 else ''})")
    values = []
    for item in items:
        try:
            values.append(float(item))
        except ValueError:
            raise UsageError(f"{allowed}, got {text!r} ({item.strip()!r} is not a number)") from None
    shear = values[2] if len(values) == 3 else None
    if shear is not None and scene is not None and scene.dim == 1:
        raise UsageError(
            f"--viscosity {text}: the third number, SHEAR, is a shear viscosity, which vanishes in 1D, "
            f"and {scene.name} is 1D here: give QUAD,LIN"
        )
    try:
        return jm.ArtificialViscosity(c_quad=values[0], c_lin=values[1], c_shear=shear)
    except ValueError as e:
        raise UsageError(f"{allowed}, got {text!r}: {e}") from None
