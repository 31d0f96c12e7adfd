"""Equinox's abstract-or-final rule, over every ``eqx.Module`` that jaxmpm defines.

Every class is either abstract (its name starts with ``Abstract`` and it declares abstract members:
``abc.abstractmethod``, ``eqx.AbstractVar``, ``eqx.AbstractClassVar``) or final (no subclass, no
abstract member left). A class implements the abstract members of its bases and overrides nothing
concrete: code is shared through functions, not inheritance.
"""

import abc
import importlib
import inspect
import pkgutil
from typing import ClassVar, get_origin

import equinox as eqx

import jaxmpm

# Names every class carries for the machinery (dataclass, abc, equinox), not members of its own.
# ``__check_init__`` is not overridden by a subclass's own: equinox runs every class's check.
_MACHINERY = {"_abc_impl"}


def _all_subclasses(cls):
    out = []
    for sub in cls.__subclasses__():
        out.append(sub)
        out.extend(_all_subclasses(sub))
    return out


def jaxmpm_modules() -> list[type]:
    """Every ``eqx.Module`` subclass defined in jaxmpm (all submodules imported first)."""
    for info in pkgutil.walk_packages(jaxmpm.__path__, "jaxmpm."):
        if info.name.rsplit(".", 1)[-1] != "__main__":  # ``python -m`` entry points run on import
            importlib.import_module(info.name)
    found = {c for c in _all_subclasses(eqx.Module) if c.__module__.split(".")[0] == "jaxmpm"}
    return sorted(found, key=lambda c: (c.__module__, c.__qualname__))


def _is_abstract(cls) -> bool:
    return bool(cls.__abstractmethods__ or cls.__abstractvars__ or cls.__abstractclassvars__)


def _members(cls) -> set[str]:
    """The names a class itself defines: attributes, methods, properties and annotated fields."""
    names = set(cls.__dict__) | set(inspect.get_annotations(cls))
    return {n for n in names if not (n.startswith("__") and n.endswith("__")) and n not in _MACHINERY}


def _declares_abstract(cls, name: str) -> bool:
    annotation = inspect.get_annotations(cls).get(name)
    if annotation is not None and get_origin(annotation) in (eqx.AbstractVar, eqx.AbstractClassVar):
        return True
    return bool(getattr(cls.__dict__.get(name), "__isabstractmethod__", False))


def violations(classes) -> list[str]:
    """Every breach of the abstract-or-final rule among ``classes`` (bases outside them are ignored)."""
    classes = list(classes)
    within = set(classes)
    out = []
    for cls in classes:
        subs = [s for s in _all_subclasses(cls) if s in within]
        named = cls.__name__.startswith("Abstract")
        if subs and not (named and _is_abstract(cls)):
            out.append(f"{cls.__qualname__} has subclasses {[s.__name__ for s in subs]} but is not abstract")
        if named and not _is_abstract(cls):
            out.append(f"{cls.__qualname__} is named Abstract* but declares no abstract member")
        if not named and _is_abstract(cls):
            left = sorted(cls.__abstractmethods__ | cls.__abstractvars__ | cls.__abstractclassvars__)
            out.append(f"{cls.__qualname__} is concrete but leaves {left} abstract")
        for base in cls.__mro__[1:]:
            if base not in within:
                continue
            for name in sorted(_members(cls) & _members(base)):
                if not _declares_abstract(base, name):
                    out.append(f"{cls.__qualname__}.{name} overrides the concrete {base.__qualname__}.{name}")
    return out


def test_every_jaxmpm_module_is_abstract_or_final():
    classes = jaxmpm_modules()
    assert {c.__name__ for c in classes} >= {"AbstractScene", "GasExpansion", "GIMP", "APIC", "NeoHookean"}
    assert violations(classes) == []


def test_the_check_finds_a_bad_tree():
    """The check itself: a concrete class with a subclass, an override of a concrete method, a
    property over a class variable, an ``Abstract*`` class with nothing abstract."""

    class AbstractShape(eqx.Module):
        kind: ClassVar[str] = "shape"
        size: eqx.AbstractVar[int]

        @abc.abstractmethod
        def area(self) -> float: ...

        def describe(self) -> str:
            return self.kind

    class Square(AbstractShape):
        size: int = 1

        @property
        def kind(self) -> str:  # replaces the class variable: a breach
            return "square"

        def area(self) -> float:  # implements an abstract method: fine
            return float(self.size**2)

        def describe(self) -> str:  # overrides a concrete method: a breach
            return "a square"

    class Tile(Square):  # subclasses a concrete class: a breach
        pass

    class AbstractNothing(eqx.Module):  # named abstract, declares nothing abstract: a breach
        pass

    class Circle(AbstractShape):  # implements only what is abstract: fine
        size: int = 1

        def area(self) -> float:
            return 3.0 * self.size**2

    found = violations([AbstractShape, Square, Tile, AbstractNothing, Circle])
    assert any("Square has subclasses ['Tile']" in v for v in found)
    assert any("Square.describe overrides the concrete" in v for v in found)
    assert any("Square.kind overrides the concrete" in v for v in found)
    assert any("AbstractNothing is named Abstract*" in v for v in found)
    assert not any(v.startswith("Circle") for v in found)
    assert violations([AbstractShape, Circle]) == []
