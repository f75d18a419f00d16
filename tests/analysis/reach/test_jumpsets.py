"""Zonotope jump sets (analysis.reach.jumpsets, the re-check's analysis.reach.recheck_jumps) against closed forms.

The 2-D example: ``x' = (−x2, x1)`` (a rotation at 1 rad/s) with a clock ``t``, from the thin box
``x1 ∈ [−1, 1]``, ``x2 ∈ [−w, w]``; at ``t = T`` a time-triggered jump resets the clock and enters a mode where
``x`` stays.  After the jump ``x = R(T) x0`` (closed form), so ``x1 − x2 = a (cos T − sin T) − b (sin T + cos T)``
for ``x0 = (a, b)``: its maximum is ``|cos T − sin T| + w (sin T + cos T)`` (0.0149 at ``T = 0.785``,
``w = 0.01``), while over the box hull of the post-jump states it is ``(cos T + w sin T) + (sin T + w cos T)``
(1.428): the requirement ``x1 − x2 < 0.5`` after the jump holds, and no box jump set can prove it.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy.linalg import expm

import analysis.reach.engine as engine
import analysis.reach.recheck_own as recheck_own
from analysis.reach import reach, recheck_flowpipe, safety_fragment, unsafe_set
from analysis.reach.jumpsets import reset_image, strip_meet, union_hull
from analysis.reach.result import zonotope_contains
from analysis.reach.sets import to_float
from analysis.reach.affine import Halfspace
from analysis.reach.zonotope import Zonotope
from analysis.stl.syntax import parse_tree
from hybrid import HybridAutomaton, Mode, Transition
from hybrid.symbolic import const, coordinates, flow_map, jump_map
from hybrid.system import HybridSystem

T = 0.785
W = 0.01
NAMES = ("x1", "x2", "t")
X = coordinates(*NAMES)


def _rotation() -> HybridSystem:
    automaton = HybridAutomaton(
        name="turn", variables=NAMES, initial_mode="one",
        modes=(Mode(name="one", invariant=X.t <= T), Mode(name="two")),
        transitions=(Transition(name="stop", source="one", target="two", guard=X.t >= T),))
    return HybridSystem(automaton=automaton, state_names=NAMES,
                        flows={"one": flow_map(-X.x2, X.x1, const(1.0) + 0.0 * X.t),
                               "two": flow_map(0.0 * X.x1, 0.0 * X.x2, const(1.0) + 0.0 * X.t)},
                        jumps={"stop": jump_map(X.x1, X.x2, 0.0 * X.t)})


INITIAL = {"x1": (-1.0, 1.0), "x2": (-W, W), "t": (0.0, 0.0)}
TRUE_MAX = abs(math.cos(T) - math.sin(T)) + W * (math.sin(T) + math.cos(T))  # closed form, see the module
BOX_MAX = (math.cos(T) + W * math.sin(T)) + (math.sin(T) + W * math.cos(T))
BOUND = 0.5


def _run(monkeypatch=None, box: bool = False):
    if box:
        monkeypatch.setattr(engine, "JUMP_ZONOTOPES", 0)
    return reach(_rotation(), INITIAL, horizon=1.0, time_step=0.01, max_jumps=2,
                 unsafe=[unsafe_set("diagonal", X.x1 - X.x2 >= BOUND, NAMES, modes=("two",))])


def test_the_closed_form_puts_the_bound_between_the_true_and_the_box_maximum():
    assert TRUE_MAX < 0.02 and BOX_MAX > 1.4 and TRUE_MAX < BOUND < BOX_MAX


def test_the_zonotope_jump_set_holds_the_post_jump_states_of_the_closed_form():
    result = _run()
    assert result.complete
    (jump,) = result.jumps
    assert jump.zonotope is not None  # a time-triggered guard met by a few segments: kept as a zonotope
    start = jump.zonotope.start()
    rng = np.random.default_rng(7)
    rotation = expm(np.array([[0.0, -1.0], [1.0, 0.0]]) * T)
    for a, b in zip(rng.uniform(-1, 1, 200), rng.uniform(-W, W, 200)):
        x = rotation @ np.array([a, b])
        assert zonotope_contains(start, np.array([x[0], x[1], 0.0]), tol=1e-9), (a, b)
    # and the saved 'after' box holds the start set
    lo, hi = jump.zonotope.hull()
    assert np.all(jump.after_lo <= lo) and np.all(hi <= jump.after_hi)


def test_the_zonotope_jump_set_proves_what_the_box_hull_cannot(monkeypatch):
    zono = _run()
    assert zono.complete and zono.distance_to(zono_unsafe := unsafe_set(
        "diagonal", X.x1 - X.x2 >= BOUND, NAMES, modes=("two",))) > 0
    top = max(float(s.zonotope.center @ [1, -1, 0] + np.abs(np.array([1, -1, 0]) @ s.zonotope.generators).sum())
              for s in zono.segments if s.mode == "two")
    # a superset of the closed form's maximum, within the tube's time spread (0.01 s at 1 rad/s: ~ 2 * 0.01 * √2)
    assert TRUE_MAX <= top < TRUE_MAX + 0.05
    boxed = _run(monkeypatch, box=True)
    assert boxed.complete and boxed.jumps[0].zonotope is None
    assert boxed.distance_to(zono_unsafe) <= 0  # the box hull reaches x1 - x2 = 1.43 > 0.5
    hi = max(float(s.hi[0] - s.lo[1]) for s in boxed.segments if s.mode == "two")
    assert hi >= BOX_MAX - 1e-9


def _fragment():
    return safety_fragment(parse_tree(f'always[0, 1] (mode == "one" or x1 - x2 < {BOUND})'), NAMES, ("mode",))


def test_the_recheck_confirms_with_its_own_zonotope_jump_sets_and_not_with_boxes(monkeypatch):
    result = _run()
    check = recheck_flowpipe(result.to_json(), _rotation(), INITIAL, _fragment())
    assert check.passed, check.failure
    assert 0 < check.margin <= BOUND - TRUE_MAX  # a lower bound of the true slack
    monkeypatch.setattr(recheck_own, "OWN_JUMP_PIECES", 0)  # the re-check's box route
    boxed = recheck_flowpipe(result.to_json(), _rotation(), INITIAL, _fragment())
    assert not boxed.passed and "requirement" in boxed.failure


def test_the_recheck_rejects_a_tampered_zonotope_jump_set():
    data = json.loads(_run().to_json())
    after = data["jumps"][0]["zonotope"]["after"]
    column = int(np.argmax(np.abs(np.array(after["generators"])).sum(axis=0)))
    for row in after["generators"]:
        row[column] *= 0.9  # a shrunk generator: the reset image of 'before' is no longer inside
    check = recheck_flowpipe(json.dumps(data), _rotation(), INITIAL, _fragment())
    assert not check.passed and "not inside its 'after' zonotope" in check.failure


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_strip_union_and_reset_hold_sampled_points(seed):
    """Points of random 3-D zonotopes in a strip lie in strip_meet; of two zonotopes in union_hull; their reset
    images in reset_image (an independent route: the points themselves, membership by a linear program)."""
    from fractions import Fraction

    rng = np.random.default_rng(seed)
    z = Zonotope(center=rng.normal(size=3), generators=rng.normal(size=(3, 5)))
    normal = rng.normal(size=3)
    bound = float(normal @ z.center)  # the strip a·x <= bound cuts z through its centre
    rows = (to_float(Halfspace(normal=tuple(Fraction(v) for v in normal), offset=Fraction(bound))),)
    cut = strip_meet(z, rows)
    other = Zonotope(center=rng.normal(size=3), generators=rng.normal(size=(3, 4)))
    both = union_hull(z, other)
    r = [[Fraction(v) for v in row] for row in rng.normal(size=(3, 3))]
    off = [Fraction(v) for v in rng.normal(size=3)]
    image = reset_image(z, r, off).start()
    rm, om = np.array([[float(v) for v in row] for row in r]), np.array([float(v) for v in off])
    for xi in rng.uniform(-1, 1, size=(300, 5)):
        x = z.center + z.generators @ xi
        if normal @ x <= bound:
            assert zonotope_contains(cut, x, tol=1e-9)
        assert zonotope_contains(both, x, tol=1e-9)
        assert zonotope_contains(image, rm @ x + om, tol=1e-9)
    for xi in rng.uniform(-1, 1, size=(100, 4)):
        assert zonotope_contains(both, other.center + other.generators @ xi, tol=1e-9)
    assert cut.generators.shape[1] >= 5 and strip_meet(z, (to_float(Halfspace(
        normal=tuple(Fraction(v) for v in normal), offset=Fraction(bound - 1e3))),)) is None


@pytest.mark.parametrize("seed", [3, 4])
def test_the_recheck_own_jump_set_holds_sampled_post_jump_points(seed):
    """analysis.reach.recheck_jumps (exact rationals): two pieces cut by a strip 0 <= t <= 0.05, their union and an
    exact reset; the reset images of sampled points of the pieces inside the strip lie in its set."""
    from fractions import Fraction

    from analysis.reach.recheck_jumps import own_jump_set
    from analysis.reach.recheck_sets import FZ

    rng = np.random.default_rng(seed)
    pieces = [FZ(center=np.append(rng.normal(size=2), 0.02 * k), gens=np.vstack([rng.normal(size=(2, 4)),
                                                                                   [0.03, 0.0, 0.01, 0.0]]),
                 err=np.full(3, 1e-3)) for k in range(2)]
    rows = [Halfspace(normal=(Fraction(0), Fraction(0), Fraction(1)), offset=Fraction(1, 20)),
            Halfspace(normal=(Fraction(0), Fraction(0), Fraction(-1)), offset=Fraction(0))]
    matrix = [[Fraction(int(i == j)) if i < 2 else Fraction(0) for j in range(3)] for i in range(3)]
    matrix[0][1] = Fraction(1, 3)  # a shear, and t := 0
    offset = [Fraction(1, 7), Fraction(0), Fraction(0)]
    got = own_jump_set(pieces, rows, matrix, offset)
    z = Zonotope(center=got.center, generators=np.hstack([got.gens, np.diag(got.err)]))
    rm = np.array([[float(v) for v in row] for row in matrix])
    om = np.array([float(v) for v in offset])
    hits = 0
    for piece in pieces:
        for xi, e in zip(rng.uniform(-1, 1, size=(400, 4)), rng.uniform(-1, 1, size=(400, 3))):
            x = piece.center + piece.gens @ xi + piece.err * e
            if 0.0 <= x[2] <= 0.05:
                hits += 1
                assert zonotope_contains(z, rm @ x + om, tol=1e-9)
    assert hits > 50
