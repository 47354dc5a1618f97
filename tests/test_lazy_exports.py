"""The rooms' lazy public names (:func:`kinegrasp_env.lazy.lazy_exports`): each name in a
room's ``__all__`` is the object its module defines, listed by ``dir()``; a name listed twice
and an unknown name are refused."""

from __future__ import annotations

import ast
import importlib
import sys
import types
from pathlib import Path

import pytest

from kinegrasp_env.lazy import lazy_exports

PACKAGE = Path(__file__).resolve().parents[1] / "kinegrasp_env"
#: Every package of kinegrasp_env whose ``__init__`` calls lazy_exports, as dotted paths
#: below kinegrasp_env (found from the files, so a new room or sub-room is checked too).
ROOMS = tuple(sorted(
    ".".join(init.parent.relative_to(PACKAGE).parts)
    for init in PACKAGE.glob("*/**/__init__.py") if "lazy_exports(" in init.read_text()))


def listed(init: Path) -> dict[str, str]:
    """name -> module, read from the ``lazy_exports(__name__, {...})`` call of an ``__init__``
    as source text (independent of the function under test)."""
    for node in ast.walk(ast.parse(init.read_text())):
        if (isinstance(node, ast.Call) and getattr(node.func, "id", None) == "lazy_exports"):
            table = ast.literal_eval(node.args[1])
            return {name: module for module, names in table.items() for name in names}
    raise AssertionError(f"{init} calls no lazy_exports")


@pytest.mark.parametrize("room", ROOMS)
def test_every_listed_name_is_its_modules_object(room):
    names = listed(PACKAGE.joinpath(*room.split(".")) / "__init__.py")
    package = importlib.import_module(f"kinegrasp_env.{room}")
    assert package.__all__ == sorted(names)
    assert package._EXPORTS == names  # the table the API reference reads
    assert set(names) <= set(dir(package))
    for name, module in names.items():
        defining = importlib.import_module(f"kinegrasp_env.{room}.{module}")
        assert getattr(package, name) is getattr(defining, name), name


def test_the_package_lists_its_starting_names():
    import kinegrasp_env

    names = listed(PACKAGE / "__init__.py")
    assert kinegrasp_env.__all__ == ["ENV_IDS", "__version__", *sorted(names)]
    assert kinegrasp_env.load_object is importlib.import_module(
        "kinegrasp_env.world.objects").load_object


def test_a_name_listed_twice_or_unknown_is_refused(monkeypatch):
    with pytest.raises(ValueError, match="'x' listed under 'a' and 'b'"):
        lazy_exports("kinegrasp_env", {"a": ("x",), "b": ("y", "x")})
    probe = types.ModuleType("kinegrasp_env.probe")  # a package of its own: nothing shared
    monkeypatch.setitem(sys.modules, probe.__name__, probe)
    getattr_, _, names = lazy_exports(probe.__name__, {"objects": ("load_object", "catalog")})
    assert names == ["catalog", "load_object"]
    assert probe._EXPORTS == {"load_object": "objects", "catalog": "objects"}
    with pytest.raises(AttributeError, match="has no attribute 'nothing'"):
        getattr_("nothing")
