"""The named-collection type (:class:`estimators.registry.Registry`): lookup and its one error
format, entries imported from ``"module:attr"`` on first use, deprecated names, the mapping
protocol, the stage registries built on it and the project's collections that are instances."""

from __future__ import annotations

import pickle
import sys
import warnings
from dataclasses import dataclass
from pathlib import Path

import pytest

from estimators import stages
from estimators.registry import Registry, StageError, StageRegistry, load_attr


@dataclass(frozen=True)
class Colour:
    name: str
    description: str = ""


def _colours() -> Registry[Colour]:
    reg: Registry[Colour] = Registry("colour", kind=Colour, also="a Colour")
    reg.register("red", Colour("red", "warm"))
    reg.register("blue", Colour("blue", "cold"), "the sky's")
    return reg


def _plugin(tmp_path: Path, text: str) -> tuple[str, str]:
    """A plug-in file in ``tmp_path`` and the name :func:`load_attr` imports it under."""
    path = tmp_path / "colour_plugin.py"
    path.write_text(text)
    import hashlib

    digest = hashlib.sha1(str(path.resolve()).encode()).hexdigest()[:10]
    return str(path), f"vrloco_plugin_colour_plugin_{digest}"


# --------------------------------------------------------------------------------- lookup


def test_get_returns_registered_entries_and_instances_of_the_kind():
    reg = _colours()
    assert reg.get("red") == Colour("red", "warm")
    green = Colour("green")
    assert reg.get(green) is green  # an instance of the kind is returned as it is
    assert reg.names() == ["red", "blue"]
    assert reg.describe() == {"red": "warm", "blue": "the sky's"}  # given, else the entry's


def test_an_unknown_name_lists_the_valid_ones_in_one_format():
    reg = _colours()
    with pytest.raises(ValueError) as err:
        reg.get("mauve")
    assert str(err.value) == "colour='mauve': unknown; valid names: red, blue, or a Colour"
    with pytest.raises(ValueError, match=r"^Paint.colour='mauve': unknown; valid names: red, "):
        reg.get("mauve", field="Paint.colour")
    with pytest.raises(ValueError, match=r"^colour=3: unknown"):
        reg.get(3)
    assert reg.get("mauve", None) is None  # with a default, as dict.get
    assert str(Registry("size").unknown("xl")) == "size='xl': unknown; valid names: "


def test_registering_checks_names_kinds_and_strings():
    reg = _colours()
    with pytest.raises(TypeError, match=r"colour 'x': an entry must be a Colour or 'module:attr'"):
        reg.register("x", 3)
    with pytest.raises(ValueError, match=r"'package\.module:attr'"):
        reg.register("x", "no_colon")
    with pytest.raises(ValueError, match="non-empty string"):
        reg.register("", Colour("x"))
    reg.register("red", Colour("red", "hot"))  # again: replaced, in its place
    assert reg.names() == ["red", "blue"] and reg["red"].description == "hot"


# ------------------------------------------------------------------- "module:attr" entries


def test_a_module_attr_entry_is_imported_on_first_use_only(tmp_path):
    path, module = _plugin(
        tmp_path, "class Teal:\n    name, description = 'teal', 'blue-green'\nTEAL = Teal()\n"
    )
    reg = Registry("colour")
    reg.register("teal", f"{path}:TEAL")
    assert module not in sys.modules and "teal" in reg and reg.names()[-1] == "teal"
    assert reg.pop("teal") == f"{path}:TEAL" and module not in sys.modules  # pop: not imported
    reg.register("teal", f"{path}:TEAL")
    teal = reg["teal"]
    assert module in sys.modules and teal.name == "teal"
    assert reg.get("teal") is teal  # imported once, kept
    assert reg.describe()["teal"] == "blue-green"


def test_a_bad_module_attr_entry_fails_when_used_naming_the_collection():
    reg = _colours()
    reg.register("ghost", "no_such_package_xyz.colours:GHOST")
    with pytest.raises(
        StageError,
        match=r"colour='no_such_package_xyz.colours:GHOST': cannot "
        r"import",
    ):
        reg["ghost"]


def test_the_load_hook_checks_what_a_string_named_and_plugins_are_opt_in(tmp_path):
    path, _ = _plugin(tmp_path, "NOT_A_COLOUR = 3\ndef make():\n    return 4\n")

    def load(obj, name, target):
        if not isinstance(obj, int):
            obj = obj()
        if obj != 3:
            raise ValueError(f"colour={target!r} names a {type(obj).__name__}, not a 3")
        return obj

    reg = Registry("colour", load=load, plugins=True)
    reg.register("three", f"{path}:NOT_A_COLOUR")
    assert reg["three"] == 3
    assert reg.get(f"{path}:NOT_A_COLOUR") == 3  # a plug-in: loaded, not registered
    assert reg.names() == ["three"]
    with pytest.raises(ValueError, match="not a 3"):
        reg.get(f"{path}:make")
    closed = Registry("colour")
    with pytest.raises(ValueError, match=r"unknown; valid names"):
        closed.get(f"{path}:NOT_A_COLOUR")  # no plugins: a string that is no name is unknown


# ----------------------------------------------------------------------- deprecated names


def test_a_renamed_name_resolves_with_a_warning_and_is_not_listed():
    reg = _colours()
    reg.rename("crimson", "red")
    with pytest.warns(DeprecationWarning, match="colour 'crimson' is now called 'red'"):
        assert reg.get("crimson") is reg["red"]
    with pytest.warns(DeprecationWarning):
        assert reg.canonical("crimson") == "red"
    with pytest.warns(DeprecationWarning):
        assert reg["crimson"] is reg["red"]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert reg.canonical("blue") == "blue" and reg.canonical(3) == 3
    assert "crimson" in reg and list(reg) == ["red", "blue"] and len(reg) == 2
    assert "crimson" not in reg.describe() and dict(reg.renamed) == {"crimson": "red"}
    with pytest.raises(ValueError, match="cannot rename 'x' to unregistered 'mauve'"):
        reg.rename("x", "mauve")


# ------------------------------------------------------------------------ mapping protocol


def test_it_is_a_mutable_mapping_like_a_dict(monkeypatch):
    reg = _colours()
    before = dict(reg)
    assert before == {"red": Colour("red", "warm"), "blue": Colour("blue", "cold")}
    assert reg == before and before == reg and reg != {"red": Colour("red", "warm")}
    assert list(reg.keys()) == ["red", "blue"] and list(reg.values()) == list(before.values())
    assert list(reg.items()) == list(before.items()) and len(reg) == 2
    assert "red" in reg and "mauve" not in reg and 3 not in reg
    with pytest.raises(KeyError):
        reg["mauve"]
    reg["green"] = Colour("green", "leafy")
    assert reg.describe()["green"] == "leafy" and list(reg)[-1] == "green"
    del reg["green"]
    assert reg == before
    with monkeypatch.context() as m:  # pytest's setitem reads through get(name, default)
        m.setitem(reg, "red", Colour("red", "hot"))
        m.setitem(reg, "mauve", Colour("mauve"))
        assert reg["red"].description == "hot" and "mauve" in reg
    assert reg == before and list(reg) == ["red", "blue"]
    assert reg.pop("mauve", None) is None
    with pytest.raises(KeyError):
        reg.pop("mauve")
    reg.clear()
    assert len(reg) == 0 and reg.names() == []
    reg.update(before)
    assert reg == before and list(reg) == list(before)
    assert repr(reg) == "<Registry 'colour': red, blue>"


# --------------------------------------------------------------------------- stages, users


def test_a_stage_registry_is_a_registry_that_builds_and_pickles_by_home():
    reg = stages.ATTITUDE
    assert isinstance(reg, StageRegistry) and isinstance(reg, Registry)
    assert pickle.loads(pickle.dumps(reg)) is reg
    assert reg["ekf"] is load_attr("estimators.attitude.ekf:EkfStage", "attitude")
    assert reg.factory("ekf") is reg["ekf"] and list(reg) == reg.names()
    with pytest.raises(
        StageError,
        match=r"^attitude='nope': unknown; valid names: ekf, "
        r".*, or 'package.module:attr'",
    ):
        reg.build("nope", 1, 100.0)
    with pytest.raises(ValueError, match=r"must be 'package\.module:attr'"):
        reg.register("x", "no_colon", "")
    homeless = StageRegistry("toy", object, "()", None)
    with pytest.raises(TypeError, match="no home"):
        pickle.dumps(homeless)


def _collections():
    from agents.benchmark.conditions import CONDITIONS
    from agents.scripted import POLICIES
    from vrloco_env.sensors.camera import LIGHTING
    from vrloco_env.sensors.imu import PRESETS
    from vrloco_env.tasks import TASKS
    from vrloco_env.techniques import TECHNIQUES
    from vrloco_env.user.population import POPULATIONS

    return {
        "task": TASKS,
        "technique": TECHNIQUES,
        "population": POPULATIONS,
        "condition": CONDITIONS,
        "policy": POLICIES,
        "imu": PRESETS,
        "lighting": LIGHTING,
    }


@pytest.mark.parametrize("collection", sorted(_collections()))
def test_every_named_collection_is_a_registry_with_the_one_error_format(collection):
    reg = _collections()[collection]
    assert isinstance(reg, Registry) and reg.names() == list(reg)
    assert set(reg.describe()) == set(reg) and all(reg.describe().values())
    with pytest.raises(
        ValueError,
        match=rf"^{reg.what}='nope': unknown; valid names: "
        rf"{reg.names()[0]}, ",
    ):
        reg.get("nope")


def test_the_camera_presets_old_name_still_imports_with_a_warning():
    import vrloco_env.sensors.camera as camera
    import vrloco_env.sensors.camera.spec as spec

    with pytest.warns(DeprecationWarning, match="CONDITIONS is now called LIGHTING"):
        assert camera.CONDITIONS is camera.LIGHTING
    with pytest.warns(DeprecationWarning, match="CONDITIONS is now called LIGHTING"):
        assert spec.CONDITIONS is spec.LIGHTING
