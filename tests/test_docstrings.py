"""Every public name of jaxmpm has a docstring.

Public: what ``jaxmpm/__init__.py`` re-exports (``from .x import Y as Y``), every module whose dotted
path has no ``_``-prefixed part and the functions and classes it defines, and every public method
and property of those classes (a method that implements an abstract one may carry its interface's
docstring, as ``inspect.getdoc`` reads it).
"""

import ast
import importlib
import inspect
import pathlib
import pkgutil
import types

import pytest

import jaxmpm


def _reexports() -> dict[str, object]:
    """The names ``jaxmpm/__init__.py`` re-exports explicitly (``import ... as`` the same name)."""
    tree = ast.parse(pathlib.Path(jaxmpm.__file__).read_text())
    names = [
        alias.name
        for node in tree.body
        if isinstance(node, ast.ImportFrom) and node.level == 1
        for alias in node.names
        if alias.asname == alias.name
    ]
    return {name: getattr(jaxmpm, name) for name in names}


def _public_modules() -> list[types.ModuleType]:
    mods = [jaxmpm]
    for info in pkgutil.walk_packages(jaxmpm.__path__, "jaxmpm."):
        if not any(part.startswith("_") for part in info.name.split(".")):
            mods.append(importlib.import_module(info.name))
    return mods


def _defined_in(mod: types.ModuleType) -> dict[str, object]:
    return {
        f"{mod.__name__}.{name}": obj
        for name, obj in vars(mod).items()
        if not name.startswith("_")
        and (inspect.isfunction(obj) or inspect.isclass(obj))
        and obj.__module__ == mod.__name__
    }


def _methods(cls: type) -> dict[str, object]:
    """Public methods and properties of ``cls`` that jaxmpm defines (on it or on a base)."""
    out = {}
    for name in dir(cls):
        if name.startswith("_"):
            continue
        owner = next((k for k in cls.__mro__ if name in k.__dict__), None)
        if owner is None or not owner.__module__.startswith("jaxmpm"):
            continue
        raw = inspect.getattr_static(cls, name)
        if isinstance(raw, property):
            out[f"{cls.__qualname__}.{name}"] = raw
        elif isinstance(raw, (classmethod, staticmethod)) or callable(raw):
            value = getattr(cls, name)
            if inspect.isfunction(value) or inspect.ismethod(value):
                out[f"{cls.__qualname__}.{name}"] = value
    return out


def _public_objects() -> dict[str, object]:
    objects = {f"jaxmpm.{name}": obj for name, obj in _reexports().items()}
    for mod in _public_modules():
        objects[mod.__name__] = mod
        objects.update(_defined_in(mod))
    for qualified, obj in list(objects.items()):
        if inspect.isclass(obj):
            objects.update({f"{obj.__module__}.{k}": v for k, v in _methods(obj).items()})
    return objects


PUBLIC = _public_objects()


def test_the_walk_reaches_the_api():
    for name in (
        "jaxmpm.simulate",
        "jaxmpm.metrics.errors",
        "jaxmpm.exact.riemann_star",
        "jaxmpm.scenes.gas_expansion.GasExpansion.exact",
        "jaxmpm.materials.AbstractMaterial.acoustic_speed",
        "jaxmpm.interpolators.gimp.GIMP.name",
        "jaxmpm.long_run.resume",
    ):
        assert name in PUBLIC


def _doc(obj) -> str | None:
    if inspect.isclass(obj):  # its own, not a base's (nor the signature a dataclass writes in its place)
        doc = obj.__dict__.get("__doc__")
        return None if doc is None or doc.startswith(f"{obj.__name__}(") else doc
    if isinstance(obj, types.ModuleType):
        return obj.__doc__
    return inspect.getdoc(obj)


@pytest.mark.parametrize("name", sorted(PUBLIC))
def test_public_name_has_a_docstring(name):
    doc = _doc(PUBLIC[name])
    assert doc and doc.strip(), f"{name} has no docstring"
