"""Step controller: increments, growth, cut-backs, clean stops, load persistence, amplitudes.

Linear springs give closed forms for every increment: a grounded spring k loaded by F has
u = F / k; a DOF imposed to v has a reaction k v.
"""
import numpy as np
import pytest

from lagamine_py.elements.base import Group, GroupResult
from lagamine_py.model import (Amplitude, Boundary, CLoad, DLoad, FoundationMotion,
                               FoundationSpec, OutputRequest, Step)
from lagamine_py.solver import run

from test_solver_fakes import (GROUND, Failing, PlasticSprings, Recorder, Springs, make_model,
                               make_problem)


def step(name="S", **kw):
    kw.setdefault("dt0", 1.0)
    kw.setdefault("dt_max", 1.0)
    return Step(name=name, **kw)


def solve(tmp_path, model, groups, kinds=None, pressure_groups=None, **rec):
    writer = Recorder(**rec)
    problem = make_problem(model, groups, kinds, pressure_groups)
    out = run(model, tmp_path, writers=[writer], problem=problem)
    return out, writer


def solve_recording_starts(tmp_path, model, groups, monkeypatch):
    """:func:`solve`, recording the predicted part of each attempt's first iterate (None where
    nothing was extrapolated): ``(out, rec, starts)``."""
    from lagamine_py.solver import newton
    import lagamine_py.solver.steps as steps_mod
    starts, orig = [], newton.solve_increment

    def spy(*a, **k):
        starts.append(k.get("predicted"))
        return orig(*a, **k)

    monkeypatch.setattr(steps_mod, "solve_increment", spy)
    out, rec = solve(tmp_path, model, groups)
    return out, rec, starts


def grounded(ks_x, ky=1.0):
    """Node r: x DOF on a grounded spring ks_x[r], y DOF on a grounded spring ky."""
    n = len(ks_x)
    return [Springs([[GROUND, 2 * r] for r in range(n)], ks_x),
            Springs([[GROUND, 2 * r + 1] for r in range(n)], ky)]


def cload(node, dof, value, **kw):
    return CLoad(f"N{node}", np.array([node]), dof, value, **kw)


def bc(node, first, last, value, **kw):
    return Boundary(f"N{node}", np.array([node]), first, last, value, **kw)


def test_dt_growth_and_linear_ramp(tmp_path):
    model = make_model(1, [step(dt0=0.1, dt_max=0.3, cloads=[cload(0, 1, 4.0)],
                                controls={"GROWTH": 1.5})])
    out, rec = solve(tmp_path, model, grounded([2.0]))
    assert out.status == 0
    expected, t = [], 0.0
    dt = 0.1
    while t < 1 - 1e-12:                       # the rule, written out independently
        d = min(dt, 1 - t)
        expected.append(d)
        t += d
        if len(expected) > 1:                  # not after the step's first increment
            dt = min(dt * 1.5, 0.3)
    assert expected[:3] == [0.1, 0.1, 0.15000000000000002]
    assert np.allclose([r.dt for r in rec.results], expected)
    for r in rec.results:
        assert r.u[0, 0] == pytest.approx(4.0 * r.step_time / 2.0, rel=1e-12)
    assert rec.results[-1].time == pytest.approx(1.0)
    assert rec.closed[0] == 0


def test_cutback_on_group_failure_keeps_committed_state(tmp_path):
    """A group that refuses increments larger than 0.3: every attempt above fails, the
    increment is cut back; the plastic state after the run is the closed form."""
    k, fy, H = 10.0, 1.0, 5.0
    inner = PlasticSprings([[GROUND, 0]], k, fy, H)
    failing = Failing(inner, lambda ctx, u: "too large" if ctx.t_new - ctx.t_old > 0.3 + 1e-12 else None)
    model = make_model(1, [step(boundaries=[bc(0, 1, 1, 0.4)])])
    out, rec = solve(tmp_path, model, [failing, Springs([[GROUND, 1]], 1.0)])
    assert out.status == 0
    assert rec.failed and all(f.dt > 0.3 for f in rec.failed)
    assert all(f.reason == "element failure" and "too large" in f.message for f in rec.failed)
    assert all(r.dt <= 0.3 + 1e-12 for r in rec.results)
    assert sum(r.cutbacks for r in rec.results) == len(rec.failed)
    assert rec.results[-1].step_time == pytest.approx(1.0)
    f = fy + H * k / (k + H) * (0.4 - fy / k)       # linear hardening, monotonic
    assert rec.results[-1].reaction[0, 0] == pytest.approx(f, rel=1e-10)
    assert rec.results[-1].reactions_by_set["N0"][0] == pytest.approx(f, rel=1e-10)


def test_cutback_on_iteration_limit(tmp_path):
    F, k, a = 40.0, 1.0, 2.0
    model = make_model(1, [step(cloads=[cload(0, 1, F)], controls={"MAXIT": 4})])
    groups = [Springs([[GROUND, 0]], k, a=a), Springs([[GROUND, 1]], 1.0)]
    out, rec = solve(tmp_path, model, groups)
    assert out.status == 0
    assert any(f.reason == "iteration limit" for f in rec.failed)
    roots = np.roots([k * a, 0, k, -F])
    d = roots[np.abs(roots.imag) < 1e-12].real[0]
    assert rec.results[-1].u[0, 0] == pytest.approx(d, rel=1e-10)


def test_clean_stop_with_status_3(tmp_path):
    """Nothing converges beyond step time 0.5: the run stops with status 3, says where and why,
    and every converged increment was handed out."""
    inner = Springs([[GROUND, 0]], 1.0)
    wall = Failing(inner, lambda ctx, u: "negative Jacobian" if ctx.t_new > 0.5 + 1e-9 else None)
    model = make_model(1, [step("PRESS", dt0=0.25, dt_min=1e-2, cloads=[cload(0, 1, 1.0)],
                                controls={"GROWTH": 1.0})])
    out, rec = solve(tmp_path, model, [wall, Springs([[GROUND, 1]], 1.0)])
    assert out.status == 3
    assert "PRESS" in out.message and "step time 0.5 " in out.message
    assert "below the minimum" in out.message and "negative Jacobian" in out.message
    assert [f.dt for f in rec.failed] == pytest.approx([0.25, 0.0625, 0.015625])
    assert [r.step_time for r in rec.results] == pytest.approx([0.25, 0.5])
    assert rec.closed == (3, out.message)


def test_max_increments(tmp_path):
    model = make_model(1, [step("S1", dt0=0.1, dt_max=0.1, max_increments=3,
                                cloads=[cload(0, 1, 1.0)])])
    out, rec = solve(tmp_path, model, grounded([1.0]))
    assert out.status == 3 and "INC=" in out.message and "S1" in out.message
    assert len(rec.results) == 3


def test_singular_model_stops_at_once_naming_the_dof(tmp_path):
    model = make_model(2, [step(cloads=[cload(0, 1, 1.0)])])
    groups = [Springs([[GROUND, 0], [GROUND, 1], [GROUND, 2]], 1.0)]      # node 1 y: nothing
    out, rec = solve(tmp_path, model, groups)
    assert out.status == 3
    assert "node 20 y" in out.message and "singular" in out.message
    assert not rec.results


def test_persistence_across_steps(tmp_path):
    k0, k1, ky = 4.0, 2.0, 5.0
    model = make_model(2, [
        # 1: force on node 0, node 1 pulled to 0.5
        step("ONE", cloads=[cload(0, 1, 10.0)], boundaries=[bc(1, 1, 1, 0.5)]),
        # 2: node 1 to 1.0 (ramped from 0.5); the force on node 0 is held
        step("TWO", dt0=0.5, dt_max=0.5, boundaries=[bc(1, 1, 1, 1.0)]),
        # 3: OP=NEW on CLOAD: the x force is removed (ramped down), a y force is applied
        step("THREE", period=2.0, dt0=0.5, dt_max=0.5, cloads=[cload(0, 2, 3.0)],
             op_new={"CLOAD"}),
        # 4: OP=NEW on BOUNDARY: node 1 released (its reaction ramps down), node 0 y imposed 0
        step("FOUR", dt0=0.5, dt_max=0.5, boundaries=[bc(0, 2, 2, 0.0)], op_new={"BOUNDARY"}),
    ])
    groups = [Springs([[GROUND, 0], [GROUND, 2]], [k0, k1]), Springs([[GROUND, 1], [GROUND, 3]], ky)]
    out, rec = solve(tmp_path, model, groups)
    assert out.status == 0, out.message
    by_step = {}
    for r in rec.results:
        by_step.setdefault(r.step, []).append(r)
    assert [len(by_step[k]) for k in (1, 2, 3, 4)] == [1, 2, 4, 2]
    for r in by_step[2]:
        s = r.step_time
        assert r.u[0, 0] == pytest.approx(10.0 / k0, rel=1e-12)
        assert r.u[1, 0] == pytest.approx(0.5 + 0.5 * s, rel=1e-12)
        assert r.reactions_by_set["N1"][0] == pytest.approx(k1 * (0.5 + 0.5 * s), rel=1e-12)
    for r in by_step[3]:
        s = r.step_time / 2.0
        assert r.u[0, 0] == pytest.approx(10.0 * (1 - s) / k0, rel=1e-12, abs=1e-14)
        assert r.u[0, 1] == pytest.approx(3.0 * s / ky, rel=1e-12)
        assert r.u[1, 0] == pytest.approx(1.0, rel=1e-12)
    for r in by_step[4]:
        s = r.step_time
        assert r.u[1, 0] == pytest.approx(1.0 - s, rel=1e-12, abs=1e-14)      # k1*1 ramped down
        assert r.u[0, 1] == pytest.approx(3.0 / ky * (1 - s), rel=1e-12, abs=1e-14)
        assert r.reactions_by_set["N0"][1] == pytest.approx(ky * r.u[0, 1] - 3.0, rel=1e-12)
        assert set(r.reactions_by_set) == {"N0"}
    assert [r.step for r in rec.results][-1] == 4 and rec.steps == [1, 2, 3, 4]


def test_amplitudes(tmp_path):
    amp = Amplitude("A", np.array([0.0, 0.5, 1.0]), np.array([0.0, 1.0, 0.2]))
    model = make_model(1, [
        step("AMP", dt0=0.25, dt_max=0.25, cloads=[cload(0, 1, 6.0, amplitude="A")],
             boundaries=[bc(0, 2, 2, 2.0, amplitude="A")]),
        step("HOLD", dt0=0.5, dt_max=0.5),
    ])
    model.amplitudes = {"A": amp}
    out, rec = solve(tmp_path, model, grounded([3.0]))
    assert out.status == 0
    assert [r.step for r in rec.results] == [1, 1, 1, 1, 2, 2]
    for r in rec.results:
        a = np.interp(r.step_time, amp.time, amp.value) if r.step == 1 else 0.2
        assert r.u[0, 0] == pytest.approx(6.0 * a / 3.0, rel=1e-12, abs=1e-15)
        assert r.u[0, 1] == pytest.approx(2.0 * a, rel=1e-12, abs=1e-15)


class FakePressure(Group):
    """A 'pressure' acting on the x DOF of node 0: f = -pressure (external load)."""

    def __init__(self):
        self.dofs = np.array([[0]])
        self.ids = np.array([1])
        self.pressure = np.zeros(1)

    def init_state(self):
        return {}

    def compute(self, u_new, u_old, state, ctx, tangent=True):
        return GroupResult(-self.pressure.reshape(1, 1), np.zeros((1, 1, 1)) if tangent else None, {})


def test_dload_sets_group_pressure_and_persists(tmp_path):
    model = make_model(1, [step("P", dt0=0.5, dt_max=0.5, dloads=[DLoad("TOP", "P", 8.0)]),
                           step("HELD", dt0=0.5, dt_max=0.5)])
    press = FakePressure()
    groups = grounded([2.0]) + [press]
    out, rec = solve(tmp_path, model, groups, kinds=["spring", "spring", "pressure"],
                     pressure_groups={"TOP": press})
    assert out.status == 0
    for r in rec.results:
        p = 8.0 * r.step_time if r.step == 1 else 8.0
        assert r.u[0, 0] == pytest.approx(p / 2.0, rel=1e-12)


class CtxRecorder(Springs):
    def __init__(self, *a, **kw):
        super().__init__(*a, **kw)
        self.seen = []

    def compute(self, u_new, u_old, state, ctx, tangent=True):
        self.seen.append((ctx.t_new, dict(ctx.foundation_old), dict(ctx.foundation_new)))
        return super().compute(u_new, u_old, state, ctx, tangent)


def test_foundation_motion_ramped_and_held(tmp_path):
    pts = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
    model = make_model(1, [step("MOVE", dt0=0.5, dt_max=0.5, motions=[FoundationMotion("F", 1.0, -2.0)],
                                output=OutputRequest(frequency=3)),
                           step("STAY", dt0=0.5, dt_max=0.5)])
    model.foundations = {"F": FoundationSpec("F", pts)}
    g = CtxRecorder([[GROUND, 0], [GROUND, 1]], 1.0)
    out, rec = solve(tmp_path, model, [g])
    assert out.status == 0
    for t_new, old, new in g.seen:
        s = min(t_new, 1.0)
        assert np.allclose(new["F"], [s, -2 * s, 0.0])          # (dx, dy, angle)
        assert np.allclose(old["F"], [max(s - 0.5, 0) if t_new <= 1 else 1.0, -2 * (max(s - 0.5, 0) if t_new <= 1 else 1.0), 0.0])
    r = rec.results[0]
    assert np.allclose(r.foundations["F"], pts + [0.5, -1.0])
    assert np.allclose(rec.results[-1].foundations["F"], pts + [1.0, -2.0])
    # *OUTPUT FREQUENCY=3 with 2 increments: only the step's last increment carries fields
    assert [r.write_fields for r in rec.results] == [False, True, True, True]


class OneSided(Springs):
    """A penalty support: force k d only while d = -u > 0 (pressed into it), nothing at d <= 0,
    as a contact point that rests on its foundation at d = 0 (open: no stiffness at all)."""

    def compute(self, u_new, u_old, state, ctx, tangent=True):
        d = -self.elongation(u_new)
        closed = d > 0
        f, K = self.blocks(-self.k * np.where(closed, d, 0.0), self.k * closed)
        return GroupResult(f, K if tangent else None, {})

    def points(self, u, state, ctx):
        return None


def test_floating_body_stops_naming_the_unrestrained_dofs(tmp_path):
    """Two nodes tied by springs, on one-sided supports that are open at d = 0, pressed down:
    nothing restrains the body in y, so the run stops (status 3) and says which DOFs float --
    with and without contact groups: no fictitious stiffness is ever added behind the user's
    back (the real contact law closes at d = 0, see tests/test_verify_contact.py)."""
    F, ks = 6.0, 1000.0
    model = make_model(2, [step(cloads=[cload(0, 2, -F), cload(1, 2, -F)])])
    groups = [OneSided([[GROUND, 1], [GROUND, 3]], ks), Springs([[0, 2], [GROUND, 0]], 10.0),
              Springs([[1, 3]], 10.0)]
    for kinds in (["contact", "spring", "spring"], ["spring", "spring", "spring"]):
        out, rec = solve(tmp_path, model, groups, kinds=kinds)
        assert out.status == 3 and "unrestrained DOFs" in out.message and " y" in out.message


def test_unavailable_solver_or_bad_control_is_a_clear_setup_error(tmp_path, monkeypatch):
    from lagamine_py.solver import linear
    model = make_model(1, [step("S", cloads=[cload(0, 1, 1.0)], controls={"MAXIT": 0})])
    out, rec = solve(tmp_path, model, grounded([1.0]))
    assert out.status == 1 and "MAXIT" in out.message and "(S)" in out.message
    assert rec.closed == (1, out.message)
    monkeypatch.setattr(linear, "pardiso_available", lambda: False)     # as without MKL
    model.steps[0].controls = {"SOLVER": "PARDISO"}
    out, rec = solve(tmp_path, model, grounded([1.0]))
    assert out.status == 1 and "pypardiso" in out.message and "(S)" in out.message


def test_progress_plain_lines_when_not_a_tty(tmp_path):
    import io

    from lagamine_py.solver.steps import Progress
    stream = io.StringIO()
    prog = Progress(enabled=True, stream=stream, total=2.0)
    prog.start(0.0)
    prog.t0 -= 10.0                             # 10 s spent on the first quarter of the run
    prog.update(0, step("LOAD"), 0.5, 3, 2, 2)
    prog.end()
    line = stream.getvalue()
    assert line.startswith(" 25%  step 1/2 LOAD  time 0.5/2  inc 3  it 2  10s")
    assert line.rstrip().endswith("ETA 30s")     # three more quarters at the same pace
    assert line.count("\n") == 1 and "\r" not in line


def test_progress_eta_of_a_resumed_run_counts_from_where_it_resumed():
    from lagamine_py.solver.steps import Progress
    prog = Progress(enabled=False, total=4.0)
    prog.start(1.0)                             # resumed at time 1 of 4
    assert prog.eta(1.0) is None
    prog.t0 -= 6.0                              # 6 s for time 1 -> 2: 2 more units at 6 s each
    assert prog.eta(2.0) == pytest.approx(12.0, rel=1e-3)


# -- the first iterate of an increment (EXTRAPOLATION) ---------------------------------------

def test_linear_extrapolation_is_exact_on_a_linear_ramp(tmp_path):
    """Linear springs under a linear ramp: from the second increment of a step the extrapolated
    first iterate is the solution, so those increments converge without a linear solve (0
    iterations); without extrapolation each takes one.  u = F(t) / k exactly either way."""
    for mode, expected in (("LINEAR", [1, 0, 0, 0]), ("NONE", [1, 1, 1, 1])):
        model = make_model(1, [step(dt0=0.25, dt_max=0.25, cloads=[cload(0, 1, 4.0)],
                                    boundaries=[bc(0, 2, 2, 0.5)],
                                    controls={"EXTRAPOLATION": mode, "GROWTH": 1.0})])
        out, rec = solve(tmp_path / mode, model, grounded([2.0], ky=3.0))
        assert out.status == 0
        assert [r.iterations for r in rec.results] == expected, mode
        for r in rec.results:
            assert r.u[0, 0] == pytest.approx(2.0 * r.step_time, rel=1e-12)
            assert r.u[0, 1] == pytest.approx(0.5 * r.step_time, rel=1e-12)


def test_extrapolation_rule_and_step_start():
    """u + (dt / dt_last) du_last; nothing to extrapolate at the start of a step or with NONE."""
    from lagamine_py.solver.predictor import extrapolated
    u, du = np.array([1.0, 2.0]), np.array([0.5, -1.0])
    assert np.allclose(extrapolated(u, (du, 0.2), 0.1, "LINEAR"), [1.25, 1.5])
    assert extrapolated(u, None, 0.1, "LINEAR") is None
    assert extrapolated(u, (du, 0.2), 0.1, "NONE") is None


def test_extrapolation_does_not_cross_steps(tmp_path, monkeypatch):
    """Step 2 reverses the load: its first increment starts from the converged state (as the
    iteration count of a linear problem cannot tell, the predicted part of the first iterate is
    recorded: None where nothing was extrapolated)."""
    model = make_model(1, [step("A", dt0=0.5, dt_max=0.5, cloads=[cload(0, 1, 4.0)]),
                           step("B", dt0=0.5, dt_max=0.5, cloads=[cload(0, 1, -4.0)])])
    out, rec, starts = solve_recording_starts(tmp_path, model, grounded([2.0]), monkeypatch)
    assert out.status == 0
    assert [s is None for s in starts] == [True, False, True, False]
    assert rec.results[-1].u[0, 0] == pytest.approx(-2.0, rel=1e-12)


def test_times_handed_out_are_those_the_steps_define(tmp_path):
    """Increments of 0.1 summed in floating point give 0.30000000000000004; writers get 0.3.
    A time that is exact in binary (0.547265625 = 0.5 + 3/64) keeps every digit."""
    from lagamine_py.solver.steps import round_time
    assert 0.1 + 0.2 != 0.3 and round_time(0.1 + 0.2, 2.0) == 0.3
    assert round_time(1.6749999999999998, 2.0) == 1.675
    assert round_time(0.547265625, 2.0) == 0.547265625
    assert round_time(1234.5000000000002, 2000.0) == 1234.5
    model = make_model(1, [step(dt0=0.1, dt_max=0.1, cloads=[cload(0, 1, 4.0)],
                                controls={"GROWTH": 1.0})])
    out, rec = solve(tmp_path, model, grounded([2.0]))
    assert out.status == 0
    assert [r.time for r in rec.results] == [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0]
