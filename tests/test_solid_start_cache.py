"""The NLGEOM kernel's start arrays (``SolidElement._kernel_start``) are kept for the Newton
iterations of an increment, recognised by the committed state's own array (identity) and the
displacement at the increment start (values): a change of either computes them again."""
import numpy as np

from lagamine_py.elements.quad import Q8PlaneStrain as Q8PE

from test_kernel_twins import kernel_laws, solid_setup


def fresh(group, u_old, eps_e):
    group._cache.pop("kernel_old_key", None)
    old, bad = group._kernel_start(u_old, eps_e)
    return old.copy(), bad.copy()


def test_start_arrays_kept_for_the_same_state_and_recomputed_for_another():
    group, state, _, u_old = solid_setup(Q8PE, kernel_laws()["ELASTIC"])
    u_old = np.ascontiguousarray(u_old, float)
    eps_e = np.ascontiguousarray(state["eps_e"], float)
    first = group._kernel_start(u_old, eps_e)
    assert group._kernel_start(u_old.copy(), eps_e)[0] is first[0]    # same state: kept
    # another start displacement with the same state: recomputed
    u2 = u_old + 1e-3
    old2, _ = group._kernel_start(u2, eps_e)
    assert np.array_equal(old2, fresh(group, u2, eps_e)[0])
    assert not np.array_equal(old2, first[0])
    first = group._kernel_start(u_old, eps_e)
    # another committed state (the next increment's), same start displacement: recomputed
    other = eps_e + 1e-4
    old, bad = group._kernel_start(u_old, other)
    ref_old, ref_bad = fresh(group, u_old, other)
    assert np.array_equal(old, ref_old) and np.array_equal(bad, ref_bad)
    assert not np.array_equal(old, first[0])
    # the same values in another array: not recognised, computed again to the same values
    again = group._kernel_start(u_old, eps_e.copy())
    assert again[0] is not first[0] and np.array_equal(again[0], first[0])


def test_the_key_holds_no_copy_of_the_state():
    group, state, _, u_old = solid_setup(Q8PE, kernel_laws()["ELASTIC"])
    eps_e = np.ascontiguousarray(state["eps_e"], float)
    group._kernel_start(np.ascontiguousarray(u_old, float), eps_e)
    assert group._cache["kernel_old_key"][1] is eps_e
