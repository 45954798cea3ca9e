"""The plugin registry: declared parameters, validation messages, discovery of built-ins."""
import pytest

from lagamine_py.laws.base import MaterialLaw
from lagamine_py.registry import REGISTRY, Param, ParamError, Registry, validate_params


class _Law(MaterialLaw):
    """A law only for its parameters."""

    def update(self, eps_e_trial, state):
        raise NotImplementedError

    params = (
        Param("E", float, bounds=(0.0, None), doc="Young's modulus"),
        Param("NU", float, 0.3, bounds=(-0.999, 0.4999)),
        Param("SUBSTEPS", int, 1, bounds=(1, None), choices=("AUTO",)),
        Param("MODE", str, "A", choices=("A", "B")),
        Param("LS", bool, False),
    )


def test_validate_converts_and_fills_defaults():
    out = validate_params(_Law, {"e": "2.1D5", "substeps": "auto", "LS": "yes"})
    assert out == {"E": 2.1e5, "NU": 0.3, "SUBSTEPS": "AUTO", "MODE": "A", "LS": True}


@pytest.mark.parametrize("given, fragment", [
    ({"EE": "1"}, "unknown parameter EE (did you mean E?)"),
    ({}, "missing required parameter E"),
    ({"E": "-1"}, "E = -1 is below its lower bound 0"),
    ({"E": "1", "NU": "0.6"}, "NU = 0.6 is above its upper bound 0.4999"),
    ({"E": "x"}, "E must be a number, got 'x'"),
    ({"E": "1", "SUBSTEPS": "2.5"}, "SUBSTEPS must be an integer"),
    ({"E": "1", "MODE": "C"}, "MODE must be one of A, B"),
    ({"E": "nan"}, "E must be finite"),
])
def test_validate_reports_each_problem_by_name(given, fragment):
    with pytest.raises(ParamError, match=None) as info:
        validate_params(_Law, given)
    assert fragment in str(info.value)


def test_registry_refuses_undeclared_parameters_and_name_clashes():
    reg = Registry()

    class NotALaw:
        params = ()

    class NoParams(_Law):
        params = [Param("E")]                        # a list, not a tuple of Param

    class NoUpdate(MaterialLaw):
        """No update()."""

    with pytest.raises(TypeError, match="must derive from lagamine_py.laws.base.MaterialLaw"):
        reg.add("laws", "X", NotALaw)
    with pytest.raises(TypeError, match="must declare"):
        reg.add("laws", "X", NoParams)
    with pytest.raises(TypeError, match="does not implement update"):
        reg.add("laws", "X", NoUpdate)
    reg.add("laws", "X", _Law, "first")
    reg.add("laws", "x", _Law, "first")            # same class again: idempotent
    other = type("Other", (_Law,), {})
    with pytest.raises(ValueError, match="clashes"):
        reg.add("laws", "X", other, "second")


def test_a_third_party_plugin_replaces_a_builtin_of_its_name_and_says_so():
    reg = Registry()
    builtin = type("Builtin", (_Law,), {})
    mine = type("Mine", (_Law,), {})
    reg.add("laws", "X", builtin, "lagamine_py 0.1.0")
    reg.add("laws", "X", mine, "my-package 1.0")
    assert reg.get("laws", "X") is mine
    assert reg.tables["laws"]["X"].replaces == "lagamine_py 0.1.0"
    reg.add("laws", "Y", mine, "my-package 1.0")       # in the other order too
    reg.add("laws", "Y", builtin, "lagamine_py 0.1.0")
    assert reg.get("laws", "Y") is mine


def test_aliases_resolve_to_the_plugin():
    assert REGISTRY.canonical("elements", "cpe8") == "Q8PE"
    assert REGISTRY.get("elements", "CAX8R") is REGISTRY.get("elements", "Q8AXR")
    assert "CPE8" not in [e.name for e in REGISTRY.entries("elements")]


def test_builtins_are_registered_under_their_deck_names():
    assert {"Q8PE", "Q8AX", "Q4PE", "Q4AX"} <= set(REGISTRY.names("elements"))
    assert {"ELASTIC", "RAMBERG_OSGOOD"} <= set(REGISTRY.names("laws"))
    assert "COULOMB" in REGISTRY.names("contact_laws")
    with pytest.raises(KeyError, match="did you mean RAMBERG_OSGOOD"):
        REGISTRY.get("laws", "RAMBERG_OSGUD")


def test_example_values_derive_from_the_declarations():
    # the default when there is one, the first choice, the midpoint of two bounds, one unit
    # (or the bound's magnitude) inside one bound; nothing for a string without choices
    assert _Law.example_values() == {"E": 1.0, "NU": 0.3, "SUBSTEPS": 1, "MODE": "A", "LS": False}
    assert Param("X", float, bounds=(-2.0, 4.0)).example() == 1.0
    assert Param("X", float, gt=0.5).example() == 1.5
    assert Param("X", float, bounds=(3.0, None)).example() == 6.0
    assert Param("X", float, bounds=(None, -1.0)).example() == -2.0
    assert Param("N", int, gt=0).example() == 1
    assert Param("N", int, bounds=(1, 3)).example() == 2
    assert Param("K", str, choices=("AUTO", "NUMPY")).example() == "AUTO"
    assert Param("NAME", str).example() is None
    for p in _Law.params:                             # every value passes its own declaration
        assert p.convert(p.example()) == p.example()
