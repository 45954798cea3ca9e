"""Small fake element groups for the solver tests (and checks that their tangents are exact).

* :class:`Springs` - 1D springs between two global DOFs, force ``k (d + a d^3)`` on the
  elongation ``d = u_j - u_i`` (a grounded spring uses DOF -1 for the ground);
* :class:`PlasticSprings` - elastic-linear-hardening springs with a history variable (the plastic
  elongation): state that must be committed only on convergence;
* :class:`Atan` - ``f = atan(d)`` springs (Newton diverges on them without a line search);
* :class:`Failing` - wraps a group and fails on demand (``when(ctx) -> message or None``);
* :class:`Recorder` - a writer that keeps what it is given.
"""
import numpy as np

from lagamine_py.elements.base import Group, GroupResult, StepContext
from lagamine_py.model import Model
from lagamine_py.output.base import Writer
from lagamine_py.solver.pattern import Pattern
from lagamine_py.solver.problem import Problem

GROUND = -1


class _TwoDof(Group):
    """Elongation of springs between DOFs ``pairs[:, 0]`` and ``pairs[:, 1]`` (ground: -1)."""

    def __init__(self, pairs, k):
        pairs = np.atleast_2d(np.asarray(pairs, np.int64))
        self.grounded = pairs[:, 0] == GROUND
        # a grounded spring is given a dummy first DOF equal to its second, with zero blocks
        self.dofs = np.where(pairs == GROUND, pairs[:, ::-1], pairs)
        self.ids = np.arange(1, len(pairs) + 1)
        self.k = np.broadcast_to(np.asarray(k, float), (len(pairs),)).copy()

    def init_state(self):
        return {}

    def elongation(self, u_new):
        u = u_new.reshape(-1)[self.dofs]
        return np.where(self.grounded, u[:, 1], u[:, 1] - u[:, 0])

    def blocks(self, f, dfdd):
        """(e, 2) forces and (e, 2, 2) tangents from the spring force and its derivative."""
        B = np.stack([-np.ones_like(f), np.ones_like(f)], axis=1)
        B[self.grounded, 0] = 0.0
        return B * f[:, None], dfdd[:, None, None] * B[:, :, None] * B[:, None, :]


class Springs(_TwoDof):
    def __init__(self, pairs, k, a=0.0):
        super().__init__(pairs, k)
        self.a = a

    def compute(self, u_new, u_old, state, ctx, tangent=True):
        d = self.elongation(u_new)
        f, K = self.blocks(self.k * (d + self.a * d**3), self.k * (1 + 3 * self.a * d**2))
        return GroupResult(f, K if tangent else None, {})


class Atan(_TwoDof):
    def compute(self, u_new, u_old, state, ctx, tangent=True):
        d = self.elongation(u_new)
        f, K = self.blocks(self.k * np.arctan(d), self.k / (1 + d**2))
        return GroupResult(f, K if tangent else None, {})


class PlasticSprings(_TwoDof):
    """Return mapping in 1D: yield |f - 0| <= fy + H alpha, with alpha the accumulated slip."""

    def __init__(self, pairs, k, fy, H):
        super().__init__(pairs, k)
        self.fy, self.H = fy, H

    def init_state(self):
        n = len(self.dofs)
        return {"dp": np.zeros(n), "alpha": np.zeros(n), "status": np.zeros(n, np.int8)}

    def compute(self, u_new, u_old, state, ctx, tangent=True):
        d = self.elongation(u_new)
        k, H = self.k, self.H
        f_tr = k * (d - state["dp"])
        phi = np.abs(f_tr) - (self.fy + H * state["alpha"])
        plastic = phi > 0
        dl = np.where(plastic, phi / (k + H), 0.0)
        f = f_tr - k * dl * np.sign(f_tr)
        dfdd = np.where(plastic, k * H / (k + H), k)
        new = {"dp": state["dp"] + dl * np.sign(f_tr), "alpha": state["alpha"] + dl,
               "status": plastic.astype(np.int8)}
        fb, K = self.blocks(f, dfdd)
        return GroupResult(fb, K if tangent else None, new)


class Failing(Group):
    """Delegates to ``inner`` but reports ``failure`` when ``when(ctx, u_new)`` returns a text."""

    def __init__(self, inner, when):
        self.inner, self.when = inner, when
        self.dofs, self.ids = inner.dofs, inner.ids
        self.calls = 0

    def init_state(self):
        return self.inner.init_state()

    def compute(self, u_new, u_old, state, ctx, tangent=True):
        self.calls += 1
        res = self.inner.compute(u_new, u_old, state, ctx, tangent)
        res.failure = self.when(ctx, u_new)
        return res


class Recorder(Writer):
    def __init__(self, outdir=None, model=None, stop_at=None):
        super().__init__(outdir or ".", model)
        self.results, self.failed, self.steps, self.closed = [], [], [], None
        self.stop_at = stop_at            # (step, increment) at which to raise KeyboardInterrupt

    def start_step(self, n, step):
        self.steps.append(n)

    def increment(self, result):
        self.results.append(result)
        if self.stop_at == (result.step, result.increment):
            raise KeyboardInterrupt

    def failed_attempt(self, info):
        self.failed.append(info)

    def close(self, status, message):
        self.closed = (status, message)


def make_model(nnodes, steps, name="fake"):
    coords = np.column_stack([np.arange(nnodes, dtype=float), np.zeros(nnodes)])
    return Model(name=name, node_ids=np.arange(1, nnodes + 1) * 10, coords=coords, steps=steps)


def make_problem(model, groups, kinds=None, pressure_groups=None):
    kinds = kinds or ["spring"] * len(groups)
    return Problem(model, list(groups), list(kinds), [f"g{k}" for k in range(len(groups))],
                   [None] * len(groups), dict(pressure_groups or {}), {},
                   Pattern(model.ndof, [g.dofs for g in groups]))


def fd_check(group, u, h=1e-6):
    """Largest difference between the assembled tangent and central differences of f."""
    n = len(u)
    pat = Pattern(n, [group.dofs])
    ctx = StepContext()
    st = group.init_state()
    res = group.compute(u.reshape(-1, 2), u.reshape(-1, 2), st, ctx, True)
    K = pat.matrix(pat.assemble_data([res.K])).toarray()
    Kfd = np.zeros((n, n))
    for j in range(n):
        e = np.zeros(n)
        e[j] = h
        fp = pat.assemble_vector([group.compute((u + e).reshape(-1, 2), u.reshape(-1, 2), st, ctx).f])
        fm = pat.assemble_vector([group.compute((u - e).reshape(-1, 2), u.reshape(-1, 2), st, ctx).f])
        Kfd[:, j] = (fp - fm) / (2 * h)
    return np.abs(K - Kfd).max() / np.abs(K).max()


def test_fake_tangents_match_finite_differences():
    rng = np.random.default_rng(0)
    u = rng.normal(size=8)
    pairs = [[GROUND, 0], [0, 2], [2, 4], [1, 3], [GROUND, 5], [6, 7]]
    assert fd_check(Springs(pairs, [1.0, 2, 3, 4, 5, 6], a=0.7), u) < 1e-8
    assert fd_check(Atan(pairs, 2.0), u) < 1e-8
    # plastic springs away from the yield kink
    g = PlasticSprings(pairs, 10.0, fy=0.3, H=2.0)
    assert fd_check(g, u) < 1e-7


def test_plastic_spring_closed_form():
    """Monotonic loading: f = fy + H k/(k+H) (d - fy/k) beyond yield (linear hardening)."""
    g = PlasticSprings([[GROUND, 0]], 10.0, fy=1.0, H=5.0)
    u = np.array([0.4, 0.0])
    res = g.compute(u.reshape(-1, 2), u.reshape(-1, 2), g.init_state(), StepContext())
    assert np.isclose(res.f[0, 1], 1.0 + 10 * 5 / 15 * (0.4 - 0.1))
