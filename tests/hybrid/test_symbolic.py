"""Tests of hybrid.symbolic: the four readings of one expression agree.

* compiled evaluation (``expr(v, m)``) == the interpreter :func:`evaluate`, bit for bit,
  and == an independent float reference built alongside the expression;
* :func:`diff` == central finite differences == CasADi's gradient of :func:`to_casadi`;
* :func:`enclose` contains every sampled value (soundness);
* :func:`level_form` is ``>= 0`` exactly on the closure of a condition;
* the errors that stand for unsupported Python idioms say what to write instead.
"""

import functools
import math
import struct

import casadi as ca
import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

import hybrid.symbolic as S
from hybrid.symbolic_core import compiled_function  # the compiled evaluator (issue 26: its own module)
from hybrid.errors import ExecutionError, ModelDefinitionError
from hybrid.symbolic import (
    MAX_COMPILED_DEPTH,
    Compare,
    Const,
    Coordinate,
    SymbolicError,
    SymbolicReset,
    SymbolicVector,
    all_true,
    any_true,
    atan2,
    coordinates,
    cos,
    depth,
    diff,
    enclose,
    evaluate,
    exp,
    flow_map,
    free_symbols,
    ite,
    jump_map,
    level_form,
    log,
    maximum,
    memory,
    minimum,
    output_map,
    param,
    render,
    reset,
    select,
    sin,
    sqrt,
    substitute,
    time,
    to_casadi,
    transcendental_terms,
)

NAMES = ("x", "y", "z", "k")  # k: the coordinate used as a select index
MEMORY = ("a", "b")
V = coordinates(*NAMES)
M = memory(*MEMORY)
PARAMS = {"p": 1.5, "q": -2.0}  # a negative parameter as a power's base once printed "-2.0 ** 2"
INDEX = {n: i for i, n in enumerate(NAMES)}


# ============================================================================ helpers
def bits(value):
    return struct.pack("<d", value)


def same_float(a, b):
    """Bit-for-bit equal floats (any NaN equals any NaN)."""
    if isinstance(a, float) and isinstance(b, float) and a != a and b != b:
        return True
    return type(a) is type(b) and bits(a) == bits(b)


def outcome(function, *args):
    """``("ok", value)`` or ``("raised", exception type)``."""
    try:
        return "ok", function(*args)
    except Exception as err:  # noqa: BLE001 - the comparison is on the exception type
        return "raised", type(err)


def assert_same_outcome(a, b):
    assert a[0] == b[0], (a, b)
    if a[0] == "ok":
        assert same_float(a[1], b[1]), (a, b)
    else:
        assert a[1] is b[1], (a, b)


class OutOfRange(Exception):
    """The reference's select index outside -1 < i < n."""


# ============================================================================ random expression trees
# A tree is generated as a spec (nested tuples), then built twice: as an expression of hybrid.symbolic
# and as an independent Python closure doing the same float operations in the same order.
const_specs = st.floats(-10.0, 10.0, allow_nan=False, allow_infinity=False).map(lambda c: ("const", c))
nonzero = st.floats(-10.0, 10.0, allow_nan=False).filter(lambda c: abs(c) > 1e-3)
leaf_specs = st.one_of(
    const_specs,
    st.sampled_from(("x", "y", "z")).map(lambda n: ("coord", n)),
    st.sampled_from(MEMORY).map(lambda n: ("mem", n)),
    st.sampled_from(sorted(PARAMS)).map(lambda n: ("param", n)),
)
COMPARE_OPS = (">=", ">", "<=", "<", "==")


def condition_specs(children):
    compare = st.tuples(st.just("cmp"), st.sampled_from(COMPARE_OPS), children, children)
    return st.one_of(
        compare,
        st.tuples(st.just("and"), compare, compare),
        st.tuples(st.just("or"), compare, compare),
        st.tuples(st.just("not"), compare),
        st.tuples(st.just("not"), st.tuples(st.sampled_from(("and", "or")), compare, st.tuples(st.just("not"), compare))),
    )


def node_specs(children, *, transcendental=False):
    lists = st.lists(children, min_size=1, max_size=3).map(tuple)
    options = [
        st.tuples(st.sampled_from(("add", "sub", "mul")), children, children),
        st.tuples(st.sampled_from(("neg", "abs")), children),
        st.tuples(st.just("pow"), children, st.integers(0, 3)),
        st.tuples(st.just("div"), children, nonzero),
        st.tuples(st.sampled_from(("min", "max")), lists),
        st.tuples(st.just("ite"), condition_specs(children), children, children),
        st.tuples(st.just("select"), st.one_of(st.just(("coord", "k")), children), lists),
    ]
    if transcendental:
        options += [st.tuples(st.sampled_from(("sin", "cos", "exp", "log", "sqrt")), children),
                    st.tuples(st.just("atan2"), children, children)]
    return st.one_of(options)


@functools.cache
def tree_specs(height, transcendental=False):
    """Trees of height <= ``height``: a leaf or (even odds) an operation on trees one level lower.

    Each level refers to the next through ``st.deferred`` so that the strategies' reprs stay small.
    """
    leaves = st.one_of(leaf_specs, st.just(("time",))) if transcendental else leaf_specs
    if height == 0:
        return leaves
    children = st.deferred(lambda: tree_specs(height - 1, transcendental))
    return st.one_of(leaves, node_specs(children, transcendental=transcendental))


expr_specs = tree_specs(4)
transcendental_specs = tree_specs(4, True)

FLOAT_OPS = {"add": lambda a, b: a + b, "sub": lambda a, b: a - b, "mul": lambda a, b: a * b}
MATH = {"sin": math.sin, "cos": math.cos, "exp": math.exp, "log": math.log, "sqrt": math.sqrt}


def build(spec):
    """``(expression, reference)``; ``reference(v, m, t, flags)`` appends to ``flags`` on a non-finite value."""
    tag = spec[0]

    def finite(value, flags):
        if not math.isfinite(value):
            flags.append(value)
        return value

    if tag == "const":
        c = spec[1]
        return Const(c), lambda v, m, t, f: c
    if tag == "coord":
        i = INDEX[spec[1]]
        return V[spec[1]], lambda v, m, t, f: v[i]
    if tag == "mem":
        name = spec[1]
        return M[name], lambda v, m, t, f: m[name]
    if tag == "param":
        value = PARAMS[spec[1]]
        return param(spec[1], value), lambda v, m, t, f: value
    if tag == "time":
        return time(), lambda v, m, t, f: t
    if tag in FLOAT_OPS:
        (ea, ra), (eb, rb) = build(spec[1]), build(spec[2])
        op = FLOAT_OPS[tag]
        expr = {"add": ea + eb, "sub": ea - eb, "mul": ea * eb}[tag]
        return expr, lambda v, m, t, f: finite(op(ra(v, m, t, f), rb(v, m, t, f)), f)
    if tag == "neg":
        ea, ra = build(spec[1])
        return -ea, lambda v, m, t, f: -ra(v, m, t, f)
    if tag == "abs":
        ea, ra = build(spec[1])
        return abs(ea), lambda v, m, t, f: abs(ra(v, m, t, f))
    if tag == "pow":
        (ea, ra), k = build(spec[1]), spec[2]
        return ea ** k, lambda v, m, t, f: finite(ra(v, m, t, f) ** k, f)
    if tag == "div":
        (ea, ra), c = build(spec[1]), spec[2]
        return ea / c, lambda v, m, t, f: finite(ra(v, m, t, f) / c, f)
    if tag in ("min", "max"):
        built = [build(s) for s in spec[1]]
        exprs, refs = [e for e, _ in built], [r for _, r in built]
        fn = min if tag == "min" else max
        expr = (minimum if tag == "min" else maximum)(*exprs)
        return expr, lambda v, m, t, f: fn([r(v, m, t, f) for r in refs])
    if tag == "ite":
        (ec, rc), (ea, ra), (eb, rb) = build_condition(spec[1]), build(spec[2]), build(spec[3])
        return ite(ec, ea, eb), lambda v, m, t, f: ra(v, m, t, f) if rc(v, m, t, f) else rb(v, m, t, f)
    if tag == "select":
        ei, ri = build(spec[1])
        built = [build(s) for s in spec[2]]
        n = len(built)

        def pick(v, m, t, f):
            i = ri(v, m, t, f)
            values = [r(v, m, t, f) for _, r in built]
            if not -1.0 < i < n:
                raise OutOfRange(i)
            return values[int(i)]

        return select(ei, [e for e, _ in built]), pick
    if tag in MATH:
        ea, ra = build(spec[1])
        fn = MATH[tag]
        return getattr(S, tag)(ea), lambda v, m, t, f: finite(fn(ra(v, m, t, f)), f)
    if tag == "atan2":
        (ea, ra), (eb, rb) = build(spec[1]), build(spec[2])
        return atan2(ea, eb), lambda v, m, t, f: math.atan2(ra(v, m, t, f), rb(v, m, t, f))
    raise AssertionError(spec)


def build_condition(spec):
    tag = spec[0]
    if tag == "cmp":
        op, (ea, ra), (eb, rb) = spec[1], build(spec[2]), build(spec[3])
        expr = {">=": lambda: ea >= eb, ">": lambda: ea > eb, "<=": lambda: ea <= eb, "<": lambda: ea < eb,
                "==": lambda: Compare("==", ea, eb)}[op]()
        py = {">=": lambda a, b: a >= b, ">": lambda a, b: a > b, "<=": lambda a, b: a <= b,
              "<": lambda a, b: a < b, "==": lambda a, b: a == b}[op]
        return expr, lambda v, m, t, f: py(ra(v, m, t, f), rb(v, m, t, f))
    if tag in ("and", "or"):
        (ea, ra), (eb, rb) = build_condition(spec[1]), build_condition(spec[2])
        if tag == "and":
            return ea & eb, lambda v, m, t, f: ra(v, m, t, f) and rb(v, m, t, f)
        return ea | eb, lambda v, m, t, f: ra(v, m, t, f) or rb(v, m, t, f)
    ea, ra = build_condition(spec[1])
    return ~ea, lambda v, m, t, f: not ra(v, m, t, f)


coordinate_values = st.one_of(
    st.floats(-20.0, 20.0, allow_nan=False),
    st.integers(-3, 3).map(float),  # ties for ==, min and max, exact zeros
    st.sampled_from((0.0, -0.0, 0.5, 2.0)),
)
points = st.tuples(coordinate_values, coordinate_values, coordinate_values, st.floats(-1.5, 3.5))
memories = st.fixed_dictionaries({"a": coordinate_values, "b": coordinate_values})


# ============================================================================ compiled == interpreter == reference
@given(expr_specs, points, memories)
def test_compiled_equals_interpreter_bit_for_bit_and_the_reference(spec, v, m):
    expr, ref = build(spec)
    compiled = outcome(expr, v, m)
    interpreted = outcome(evaluate, expr, v, m)
    assert_same_outcome(compiled, interpreted)
    flags = []
    reference = outcome(ref, v, m, 0.0, flags)
    if reference[0] == "raised":
        # an OverflowError of x ** k, or a select out of range; constant folding (0 * e -> 0) may drop the
        # subtree that raised, so the expression may still have a value
        assert reference[1] in (OverflowError, OutOfRange)
        if compiled[0] == "raised":
            assert compiled[1] is (ExecutionError if reference[1] is OutOfRange else OverflowError)
        return
    if compiled[0] == "raised":
        assert compiled[1] in (ExecutionError, OverflowError)  # raised inside a subtree the reference reached
        raise AssertionError(f"the expression {render(expr)} raised {compiled[1]} but the reference gave "
                             f"{reference[1]!r}")
    if flags:
        return  # inf or NaN met on the way: folding (0 * inf) and flattening (nested min with NaN) may differ
    # the same float operations in the same order: equal values (constant folding of `e + 0` or `0 * e`
    # may only change the sign of a zero)
    assert compiled[1] == reference[1], (render(expr), compiled, reference)


@given(expr_specs, points, memories)
def test_a_reset_a_jump_map_a_flow_and_an_output_compile_to_the_interpreter(spec, v, m):
    expr, _ = build(spec)
    other = expr * 2.0 - V.x
    want = outcome(lambda: (evaluate(expr, v, m), evaluate(other, v, m)))
    r = reset(first=expr, second=other)
    got = [
        outcome(lambda: tuple(r(v, m).values())),
        outcome(lambda: jump_map(expr, other)(v, m)),
        outcome(lambda: flow_map(expr, other)(0.5, v, m)),
    ]
    if not free_symbols(expr)["memory"]:
        got.append(outcome(lambda: output_map(expr, other)(0.5, v)))
    for g in got:
        assert g[0] == want[0], (g, want)
        if g[0] == "ok":
            assert len(g[1]) == 2 and all(same_float(a, b) for a, b in zip(g[1], want[1])), (g, want)
        else:
            assert g[1] is want[1]


@pytest.mark.parametrize(
    "expr, hand",
    [
        (minimum(M.a - V.x, V.y - 5.0), lambda v, m: min(m["a"] - v[0], v[1] - 5.0)),
        ((V.x * V.y - 3.0 * V.z) ** 2 / 4.0 + abs(V.x), lambda v, m: (v[0] * v[1] - 3.0 * v[2]) ** 2 / 4.0 + abs(v[0])),
        (ite((V.x >= 0.0) & ~(V.y < 1.0), V.x * 2.0, maximum(V.y, -V.z, 0.5)),
         lambda v, m: v[0] * 2.0 if (v[0] >= 0.0 and not (v[1] < 1.0)) else max(v[1], -v[2], 0.5)),
        (select(V.k, (V.x, V.y + 1.0, V.z * V.z)), lambda v, m: (v[0], v[1] + 1.0, v[2] * v[2])[int(v[3])]),
        (sin(V.x) * exp(-V.y) + sqrt(abs(V.z)) + atan2(V.y, V.x) - log(1.0 + V.x * V.x),
         lambda v, m: math.sin(v[0]) * math.exp(-v[1]) + math.sqrt(abs(v[2])) + math.atan2(v[1], v[0])
         - math.log(1.0 + v[0] * v[0])),
        (param("q", -2.0) ** 2 * V.x + Const(-3.0) ** 3, lambda v, m: (-2.0) ** 2 * v[0] + (-3.0) ** 3),
        (2.0 - V.x * 3.0 + 1.0 / 8.0 * M.b, lambda v, m: 2.0 - v[0] * 3.0 + 1.0 / 8.0 * m["b"]),
        (diff(log(V.x * V.x + 1.0), "x"), lambda v, m: (v[0] + v[0]) * (1.0 / (v[0] * v[0] + 1.0))),
        (cos(M.a) ** 0 - (V.y - -0.5), lambda v, m: math.cos(m["a"]) ** 0 - (v[1] - -0.5)),
    ],
    ids=["thermostat", "polynomial", "ite", "select", "transcendental", "negative_base", "reflected", "inv",
         "pow0"],
)
@given(v=st.tuples(st.floats(-20, 20), st.floats(-20, 20), st.floats(-20, 20), st.floats(0.0, 2.999)),
       m=memories)
def test_fixed_expressions_equal_hand_written_lambdas_bit_for_bit(expr, hand, v, m):
    want = outcome(hand, v, m)
    assert_same_outcome(outcome(expr, v, m), want)
    assert_same_outcome(outcome(evaluate, expr, v, m), want)


def test_negative_literal_as_a_power_base_regression():
    """``(-2.0) ** 2`` once compiled to the source ``-2.0 ** 2``, i.e. ``-(2.0 ** 2)``."""
    assert (Const(-2.0) ** 2)((), {}) == 4.0
    assert (param("q", -2.0) ** 2 + V.x)((1.0, 0.0, 0.0, 0.0), {}) == 5.0
    assert (Const(-0.0) ** 3)((), {}) == evaluate(Const(-0.0) ** 3)


def test_reflected_operators_and_folding():
    v = (3.0, 2.0, 0.0, 0.0)
    assert (1.0 + V.x)(v, {}) == 4.0 and (1.0 - V.x)(v, {}) == -2.0 and (2.0 * V.x)(v, {}) == 6.0
    assert (V.x + 0.0) is V.x and (1.0 * V.x) is V.x and isinstance(0.0 * V.x, Const)
    assert -(-V.x) is V.x and +V.x is V.x
    assert isinstance(Const(2.0) + 3.0, Const) and (Const(2.0) + 3.0).value == 5.0
    assert (V.x + np.float64(2.0))(v, {}) == 5.0  # a numpy scalar is a number


# ============================================================================ deep trees
def deep_chain(n, *, shared=False):
    """A tree of ``n`` steps mixing every node kind, with its float reference.

    ``shared``: every step uses the previous term two or three times (a DAG whose written-out
    size grows exponentially: it must be interpreted with a memo, not compiled).
    """
    e, steps = V.x, []
    for i in range(n):
        kind = i % 5
        if kind == 0:
            e = e * 0.5 + V.y
        elif kind == 1:
            e = minimum(e, V.z + float(i))
        elif kind == 2:
            e = ite(e > 1.0, e - 1.0, abs(e)) if shared else ite(V.y > 0.5, e - 1.0, abs(V.z))
        elif kind == 3:
            e = select(V.k, (e, e + 1.0) if shared else (e, V.x + 1.0))
        else:
            e = -(e / 4.0) + M.a
        steps.append(kind)

    def reference(v, m):
        r = v[0]
        for i, kind in enumerate(steps):
            if kind == 0:
                r = r * 0.5 + v[1]
            elif kind == 1:
                r = min(r, v[2] + float(i))
            elif kind == 2:
                if shared:
                    r = r - 1.0 if r > 1.0 else abs(r)
                else:
                    r = r - 1.0 if v[1] > 0.5 else abs(v[2])
            elif kind == 3:
                r = ((r, r + 1.0) if shared else (r, v[0] + 1.0))[int(v[3])]
            else:
                r = -(r / 4.0) + m["a"]
        return r

    return e, reference


def is_compiled(expr, kind="condition"):
    return compiled_function(expr, kind).__code__.co_filename.startswith(f"<symbolic {kind} ")


def random_points(seed, count=20):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        v = (float(rng.uniform(-5, 5)), float(rng.uniform(-5, 5)), float(rng.uniform(-5, 5)),
             float(rng.uniform(0, 1.999)))
        yield v, {"a": float(rng.uniform(-5, 5)), "b": 0.0}


@pytest.mark.parametrize("n, shared", [(10, False), (40, False), (150, False), (30, True), (150, True)])
def test_deep_trees_fall_back_to_the_interpreter_and_stay_exact(n, shared):
    e, reference = deep_chain(n, shared=shared)
    if n >= 40:
        assert depth(e) > MAX_COMPILED_DEPTH
    assert is_compiled(e) == (depth(e) <= MAX_COMPILED_DEPTH and not shared)
    for v, m in random_points(n):
        want = reference(v, m)
        assert same_float(e(v, m), want)
        assert same_float(evaluate(e, v, m), want)


def test_compilation_limit_is_the_depth_of_the_tree():
    e = V.x
    for _ in range(MAX_COMPILED_DEPTH - 1):
        e = abs(e)
    assert depth(e) == MAX_COMPILED_DEPTH and is_compiled(e)
    deeper = abs(e)
    assert depth(deeper) == MAX_COMPILED_DEPTH + 1 and not is_compiled(deeper)
    assert deeper((-2.5,), {}) == e((-2.5,), {}) == 2.5


def test_the_deepest_compiled_tree_nests_within_the_parser_limits():
    """A select nests two parentheses per level in the compiled source (call and tuple): still compiles."""
    e = V.x
    while depth(e) < MAX_COMPILED_DEPTH:
        e = select(V.k, (e, V.y))
    e2 = V.x
    while depth(e2) + 3 <= MAX_COMPILED_DEPTH:
        e2 = ite(select(V.k, (e2, V.y)) >= 0.0, V.y + 1.0, -V.z)
    for expr in (e, e2):
        assert depth(expr) <= MAX_COMPILED_DEPTH and is_compiled(expr)
        for v, m in random_points(1, 5):
            assert same_float(expr(v, m), evaluate(expr, v, m))


def test_deep_maps_fall_back_to_the_interpreter():
    e, reference = deep_chain(120)
    assert not is_compiled(e)
    for v, m in random_points(2, 5):
        want = reference(v, m)
        assert reset(r=e, s=V.x)(v, m) == {"r": want, "s": v[0]}
        assert jump_map(e, V.y)(v, m) == (want, v[1])
        assert flow_map(e, time())(2.0, v, m) == (want, 2.0)
        no_memory = substitute(e, memory={"a": Const(m["a"])})
        assert output_map(no_memory, time())(3.0, v) == (want, 3.0)


# ============================================================================ diff
# CasADi: one SX symbol per coordinate; memory and parameters are numbers.
X = ca.SX.sym("X", len(NAMES))
CASADI_COORDS = {n: X[i] for i, n in enumerate(NAMES)}


def casadi_gradient(expr, v, m):
    cs = to_casadi(expr, CASADI_COORDS, {k: float(val) for k, val in m.items()})
    if not isinstance(cs, ca.SX):
        return np.zeros(len(NAMES))
    g = ca.Function("g", [X], [ca.gradient(cs, X)])
    return np.array(g(np.array(v, dtype=float))).ravel()


def casadi_value(expr, v, m):
    cs = to_casadi(expr, CASADI_COORDS, {k: float(val) for k, val in m.items()})
    if not isinstance(cs, ca.SX):
        return float(cs)
    return float(ca.Function("f", [X], [cs])(np.array(v, dtype=float)))


def magnitude(node, v, m):
    """A bound on |value| of every subterm of an arithmetic tree (coordinates taken as |x| + 1).

    It bounds the rounding error of an evaluation (a few ulps of this per operation) and, since
    |x| + 1 covers a neighbourhood of radius 1, the derivatives that enter a finite difference.
    """
    if isinstance(node, Const):
        return abs(node.value)
    if isinstance(node, Coordinate):
        return abs(v[node.index]) + 1.0
    if isinstance(node, S.MemoryRef):
        return abs(m[node.name])
    if isinstance(node, S.Param):
        return abs(node.value)
    if isinstance(node, S.Ite):
        return max(magnitude(node.then, v, m), magnitude(node.otherwise, v, m))
    if isinstance(node, S.Select):
        return max(magnitude(o, v, m) for o in node.options)
    a = [magnitude(arg, v, m) for arg in node.args]
    op = node.op
    if op in ("add", "sub"):
        return a[0] + a[1]
    if op == "mul":
        return a[0] * a[1]
    if op == "div":
        return a[0] / abs(node.args[1].value)
    if op in ("neg", "abs"):
        return a[0]
    if op == "pow":
        return a[0] ** int(node.args[1].value)
    if op in ("min", "max"):
        return max(a)
    raise AssertionError(op)


def finite_difference(expr, v, m, i, h):
    up, down = list(v), list(v)
    up[i] += h
    down[i] -= h
    return (evaluate(expr, up, m) - evaluate(expr, down, m)) / (up[i] - down[i])


polynomial_specs = st.recursive(
    st.one_of(st.floats(-3.0, 3.0).map(lambda c: ("const", c)),
              st.sampled_from(("x", "y", "z")).map(lambda n: ("coord", n)),
              st.sampled_from(MEMORY).map(lambda n: ("mem", n))),
    lambda c: st.one_of(
        st.tuples(st.just("add"), c, c), st.tuples(st.just("sub"), c, c), st.tuples(st.just("mul"), c, c),
        st.tuples(st.just("neg"), c), st.tuples(st.just("pow"), c, st.integers(0, 3)),
        st.tuples(st.just("div"), c, nonzero),
    ),
    max_leaves=8,
)
smooth_points = st.tuples(st.floats(-2.0, 2.0), st.floats(-2.0, 2.0), st.floats(-2.0, 2.0), st.just(0.5))
small_memories = st.fixed_dictionaries({"a": st.floats(-2.0, 2.0), "b": st.floats(-2.0, 2.0)})


@given(polynomial_specs, smooth_points, small_memories)
def test_diff_of_polynomials_agrees_with_finite_differences_and_casadi(spec, v, m):
    expr, _ = build(spec)
    scale = magnitude(expr, v, m)
    assume(scale < 1e8)
    grad_cs = casadi_gradient(expr, v, m)
    for i, name in enumerate(("x", "y", "z")):
        d = diff(expr, name)
        exact = d(v, m)
        assert same_float(exact, evaluate(d, v, m))
        # h = 1e-6: truncation h^2/6 |f'''| and rounding ~50 eps scale / h are both below 1e-8 scale
        # (|f'''| <= 27^3 scale at |x| + 1 for degree <= 27), far inside the 1e-6 (1 + scale) tolerance
        fd = finite_difference(expr, v, m, i, 1e-6)
        assert abs(fd - exact) <= 1e-6 * (1.0 + scale), (render(expr), name, fd, exact)
        # CasADi differentiates the same tree exactly: only the operation order differs
        d_scale = magnitude(d, v, m)
        assert abs(grad_cs[i] - exact) <= 1e-12 * (1.0 + d_scale), (render(expr), name, grad_cs[i], exact)
    assert diff(expr, V.k)(v, m) == 0.0


def kink_free(*gaps):
    return all(abs(g) > 1e-3 for g in gaps)


PIECEWISE = [
    # (expression, kinks: functions of (x, y, z, k) that must stay away from zero)
    (minimum(V.x * V.y, V.x - V.y) + abs(V.x - 2.0 * V.y) * maximum(V.x, V.y ** 2),
     lambda x, y, z, k: (x * y - (x - y), x - 2 * y, x - y * y)),
    (maximum(V.x, V.y, V.z) - minimum(V.x * 2.0, V.z, -V.y),
     lambda x, y, z, k: (x - y, y - z, x - z, 2 * x - z, z + y, 2 * x + y)),
    (ite(V.x > V.y, V.x * V.x, V.y - V.x) + ite(~(V.z <= 0.5) | (V.y >= 1.0), V.z ** 3, -V.z),
     lambda x, y, z, k: (x - y, z - 0.5, y - 1.0)),
    (select(V.k, (V.x * V.y, V.x + V.z, V.z ** 3)) * abs(V.y),
     lambda x, y, z, k: (k - 1.0, k - 2.0, y)),
    (abs(abs(V.x) - 1.0) * V.y, lambda x, y, z, k: (x, abs(x) - 1.0)),
]
SMOOTH = [
    sin(V.x * V.y) + cos(V.x - V.z) * exp(0.3 * V.y),
    log(1.0 + V.x * V.x + V.y * V.y) + sqrt(4.0 + V.x * V.z),
    atan2(V.y + 3.0, V.x),
    atan2(V.x, 4.0 + V.y * V.z),  # 4 + yz >= 0.39 on the box: away from the branch cut
    exp(sin(V.x) * log(2.0 + cos(V.y))) / 3.0,
    sqrt(V.x * V.x + V.y * V.y + 1.0) ** 3 - M.a * log(3.0 + V.z),
    cos(exp(V.x / 2.0)) * sin(M.b * V.y + V.z),
]
piecewise_points = st.tuples(st.floats(-1.9, 1.9), st.floats(-1.9, 1.9), st.floats(-1.9, 1.9), st.floats(0.0, 2.99))


def three_way(expr, v, m, rtol_fd):
    f = expr(v, m)
    grad_cs = casadi_gradient(expr, v, m)
    for i, name in enumerate(NAMES):
        d = diff(expr, name)
        exact = d(v, m)
        assert same_float(exact, evaluate(d, v, m))
        fd = finite_difference(expr, v, m, i, 1e-6)
        assert abs(fd - exact) <= rtol_fd * (1.0 + abs(f) + abs(exact)), (render(expr), name, fd, exact)
        assert abs(grad_cs[i] - exact) <= 1e-11 * (1.0 + abs(exact)), (render(expr), name, grad_cs[i], exact)


@pytest.mark.parametrize("case", range(len(PIECEWISE)))
@given(v=piecewise_points, m=small_memories)
def test_diff_of_piecewise_terms_away_from_kinks(case, v, m):
    expr, kinks = PIECEWISE[case]
    assume(kink_free(*kinks(*v)))
    # 1e-3 from every kink: a gradient below ~100 moves each kink function by < 1e-4 over the 2e-6 stencil
    three_way(expr, v, m, 1e-6)


@pytest.mark.parametrize("case", range(len(SMOOTH)))
@given(v=piecewise_points, m=small_memories)
def test_diff_of_transcendental_terms(case, v, m):
    three_way(SMOOTH[case], v, m, 1e-6)


def test_diff_with_respect_to_memory_time_and_second_derivatives():
    t = time()
    e = M.a * V.x ** 2 + sin(t) * M.b
    assert evaluate(diff(e, M.a), (3.0,), {"a": 2.0, "b": 1.0}) == 9.0
    assert evaluate(diff(e, M.b), (3.0,), {"a": 2.0, "b": 1.0}, t=0.5) == math.sin(0.5)
    assert evaluate(diff(e, t), (3.0,), {"a": 2.0, "b": 4.0}, t=0.5) == math.cos(0.5) * 4.0
    assert diff(e, "x") is not diff(e, V.x) and evaluate(diff(e, "x"), (3.0,), {"a": 2.0, "b": 1.0}) == 12.0
    assert isinstance(diff(V.y * 3.0, "x"), Const) and diff(V.y * 3.0, "x").value == 0.0
    assert diff(V.x ** 0, "x").value == 0.0
    # second derivatives of the internal reciprocal (log, sqrt, atan2): d^2/dx^2 log x = -1 / x^2
    for x in (0.3, 1.0, 7.5):
        assert diff(diff(log(V.x), "x"), "x")((x,), {}) == pytest.approx(-1.0 / x ** 2, rel=1e-15)
        second = diff(diff(sqrt(V.x), "x"), "x")((x,), {})
        assert second == pytest.approx(-0.25 * x ** -1.5, rel=1e-14)


@given(expr_specs, points, memories)
def test_to_casadi_evaluates_like_the_interpreter(spec, v, m):
    expr, ref = build(spec)
    flags = []
    reference = outcome(ref, v, m, 0.0, flags)
    assume(reference[0] == "ok" and not flags)  # casadi picks a select option out of range instead of raising
    want = evaluate(expr, v, m)
    got = casadi_value(expr, v, m)
    assert abs(got - want) <= 1e-12 * (1.0 + magnitude(expr, v, m)), (render(expr), got, want)


# ============================================================================ enclose
interval_ends = st.floats(-10.0, 10.0)
widths = st.one_of(st.just(0.0), st.floats(0.0, 10.0))
boxes = st.fixed_dictionaries({n: st.tuples(interval_ends, widths) for n in (*NAMES, *MEMORY, "t")})
fractions = st.lists(st.tuples(*[st.sampled_from((0.0, 1.0)) | st.floats(0.0, 1.0)
                                 for _ in range(len(NAMES) + len(MEMORY) + 1)]), min_size=1, max_size=12)


def interval(lo_width):
    lo, w = lo_width
    return lo, lo + w


def inside(iv, f):
    lo, hi = iv
    return min(hi, max(lo, lo + f * (hi - lo)))


def check_enclosure(expr, box, samples):
    bounds = {n: interval(box[n]) for n in NAMES}
    mem = {n: interval(box[n]) for n in MEMORY}
    tb = interval(box["t"])
    lo, hi = enclose(expr, bounds, mem, tb)
    assert lo <= hi
    for f in samples:
        names = (*NAMES, *MEMORY, "t")
        pt = {n: inside(interval(box[n]), f[j]) for j, n in enumerate(names)}
        v = tuple(pt[n] for n in NAMES)
        m = {n: pt[n] for n in MEMORY}
        try:
            value = evaluate(expr, v, m, pt["t"])
        except (ValueError, OverflowError, ZeroDivisionError, ExecutionError):
            continue  # outside the domain (log, sqrt, select) or out of float range
        if value != value:
            continue
        assert lo <= value <= hi, (render(expr), (lo, hi), value, pt)
    return lo, hi


@given(expr_specs, boxes, fractions)
def test_enclosure_contains_every_sampled_value(spec, box, samples):
    expr, _ = build(spec)
    check_enclosure(expr, box, samples)


@given(transcendental_specs, boxes, fractions)
def test_enclosure_of_transcendental_terms_is_sound(spec, box, samples):
    expr, _ = build(spec)
    check_enclosure(expr, box, samples)


@pytest.mark.parametrize("case", range(len(SMOOTH)))
@given(box=boxes, samples=fractions)
def test_enclosure_of_derivatives_with_reciprocals_is_sound(case, box, samples):
    e = SMOOTH[case]
    for name in ("x", "y"):
        check_enclosure(diff(e, name), box, samples)


@given(st.floats(-1e6, 1e6), st.floats(0.0, 8.0), st.lists(st.floats(0.0, 1.0), min_size=1, max_size=20))
def test_trigonometric_enclosures_over_wide_and_far_intervals(lo, width, fs):
    for f in (sin, cos):
        ilo, ihi = enclose(f(V.x), {"x": (lo, lo + width)})
        assert -1.0 <= ilo <= ihi <= 1.0
        for frac in [0.0, 1.0, *fs]:
            x = inside((lo, lo + width), frac)
            assert ilo <= f(V.x)((x,), {}) <= ihi


@given(st.floats(-50.0, 50.0), st.sampled_from(["poly", "ite", "trig", "select"]))
def test_degenerate_intervals(c, which):
    e = {"poly": V.x * V.x - 2.0 * V.x + 1.0, "ite": ite(V.x > 0.0, V.x, -V.x) * 3.0,
         "trig": exp(sin(V.x)) + sqrt(abs(V.x)), "select": select(abs(V.x) / 100.0, (V.x, V.x + 1.0))}[which]
    lo, hi = enclose(e, {"x": (c, c)})
    value = e((c,), {})
    assert lo <= value <= hi
    if which == "poly":  # a few ulps per operation
        assert hi - lo <= 1e-12 * (1.0 + c * c)


def test_unbounded_coordinates_give_infinite_bounds():
    assert enclose(V.x + 1.0, {}) == (-math.inf, math.inf)
    assert enclose(M.a * 2.0, {"x": (0.0, 1.0)}) == (-math.inf, math.inf)  # memory without bounds
    lo, hi = enclose(V.x ** 2, {})
    assert lo <= 0.0 <= 1e-300 and hi == math.inf
    assert enclose(abs(V.x), {})[1] == math.inf and enclose(abs(V.x), {})[0] == 0.0
    assert enclose(exp(V.x), {}) == (0.0, math.inf)
    assert enclose(sin(V.x), {}) == (-1.0, 1.0)
    assert enclose(minimum(V.x, 3.0), {}) == (-math.inf, 3.0)
    assert enclose(log(V.x), {"x": (0.0, 1.0)}) == (-math.inf, math.inf)  # reaches log 0
    assert enclose(sqrt(V.x), {"x": (-1.0, 1.0)}) == (-math.inf, math.inf)
    assert enclose(0.0 * V.x + V.y, {"y": (1.0, 2.0)}) == (1.0, 2.0)  # folded: 0 * x is 0


def test_enclosure_of_select():
    opts = (Const(10.0), V.y, Const(30.0))
    e = select(V.k, opts)
    yb = {"y": (-1.0, 1.0)}
    assert enclose(e, {"k": (-2.0, 0.5), **yb}) == (-math.inf, math.inf)  # may leave -1 < k
    assert enclose(e, {"k": (0.0, 3.0), **yb}) == (-math.inf, math.inf)  # may reach k = n
    assert enclose(e, {"k": (-1.0, 0.0), **yb}) == (-math.inf, math.inf)  # k = -1 is outside
    assert enclose(e, {"k": (-0.5, -0.2), **yb}) == (10.0, 10.0)  # int() truncates towards zero: option 0
    assert enclose(e, {"k": (0.2, 0.9), **yb}) == (10.0, 10.0)
    assert enclose(e, {"k": (1.0, 1.5), **yb}) == (-1.0, 1.0)
    assert enclose(e, {"k": (0.5, 2.9), **yb}) == (-1.0, 30.0)
    with pytest.raises(ExecutionError):
        e((0.0, 0.0, 0.0, 3.0), {})


def test_enclosure_survives_overflow():
    """float ** int and math.exp raise OverflowError: the enclosure says +inf instead (found by this suite)."""
    assert enclose(V.x ** 2, {"x": (0.0, 1e200)})[1] == math.inf
    assert enclose(V.x ** 3, {"x": (-1e200, 0.0)})[0] == -math.inf
    assert enclose(exp(V.x), {"x": (800.0, 900.0)})[1] == math.inf
    assert enclose(exp(V.x), {"x": (800.0, 900.0)})[0] > 1e300
    # [inf, inf] - [inf, inf] once gave NaN bounds that min() dropped: (1, 1), though x^2 - y^2 = 0 here
    lo, hi = enclose(minimum(1.0, V.x ** 2 - V.y ** 2), {"x": (1e200, 1e200), "y": (1e200, 1e200)})
    assert lo <= 0.0 and hi == 1.0


# ============================================================================ level form
condition_leaves = st.recursive(
    st.one_of(st.integers(-2, 2).map(lambda c: ("const", float(c))),
              st.sampled_from(("x", "y", "z")).map(lambda n: ("coord", n))),
    lambda c: st.one_of(st.tuples(st.just("add"), c, c), st.tuples(st.just("sub"), c, c),
                        st.tuples(st.just("mul"), c, c), st.tuples(st.just("abs"), c),
                        st.tuples(st.just("min"), st.lists(c, min_size=2, max_size=2).map(tuple))),
    max_leaves=3,
)
integer_points = st.tuples(*[st.integers(-3, 3).map(float) | st.floats(-3, 3) for _ in range(3)], st.just(0.0))
NEGATED = {">=": "<", ">": "<=", "<=": ">", "<": ">=", "==": "!="}


def closed_holds(spec, v, negate=False):
    """Whether the closure of the condition (``not`` pushed inside) holds at ``v`` (independent reference)."""
    tag = spec[0]
    if tag == "cmp":
        op = NEGATED[spec[1]] if negate else spec[1]
        a = build(spec[2])[1](v, {}, 0.0, [])
        b = build(spec[3])[1](v, {}, 0.0, [])
        return {">=": a >= b, ">": a >= b, "<=": a <= b, "<": a <= b, "==": a == b}[op]
    if tag == "not":
        return closed_holds(spec[1], v, not negate)
    both = [closed_holds(spec[1], v, negate), closed_holds(spec[2], v, negate)]
    conjunction = (tag == "and") != negate
    return all(both) if conjunction else any(both)


def has_negated_equality(spec, negate=False):
    if spec[0] == "cmp":
        return spec[1] == "==" and negate
    if spec[0] == "not":
        return has_negated_equality(spec[1], not negate)
    return has_negated_equality(spec[1], negate) or has_negated_equality(spec[2], negate)


@given(condition_specs(condition_leaves), integer_points)
def test_level_form_is_nonnegative_exactly_on_the_closed_condition(spec, v):
    condition, _ = build_condition(spec)
    if has_negated_equality(spec):
        with pytest.raises(SymbolicError, match="!="):
            level_form(condition)
        return
    level = level_form(condition)
    assert (level(v, {}) >= 0.0) == closed_holds(spec, v), (render(condition), render(level), v)
    assert same_float(condition(v, {}), level(v, {}))  # a condition called directly is its level form
    assert same_float(condition.level()(v, {}), level(v, {}))
    if evaluate(condition, v, {}):
        assert level(v, {}) >= 0.0  # the condition itself holds: inside its closure


@pytest.mark.parametrize(
    "condition, level",
    [
        (V.x >= 5.0, lambda x: x - 5.0),
        (V.x > 5.0, lambda x: x - 5.0),
        (V.x <= 5.0, lambda x: 5.0 - x),
        (V.x < 5.0, lambda x: 5.0 - x),
        (Compare("==", V.x, Const(5.0)), lambda x: -abs(x - 5.0)),
        ((V.x >= 1.0) & (V.x <= 3.0), lambda x: min(x - 1.0, 3.0 - x)),
        ((V.x <= 1.0) | (V.x >= 3.0), lambda x: max(1.0 - x, x - 3.0)),
        (~(V.x >= 5.0), lambda x: 5.0 - x),
        (~((V.x >= 1.0) & (V.x <= 3.0)), lambda x: max(1.0 - x, x - 3.0)),
        (~~(V.x > 2.0), lambda x: x - 2.0),
        (~Compare("!=", V.x, Const(2.0)), lambda x: -abs(x - 2.0)),
        (all_true(V.x >= 0.0, V.x <= 4.0, V.x >= 1.0), lambda x: min(x, 4.0 - x, x - 1.0)),
        (any_true(V.x >= 4.0), lambda x: x - 4.0),
    ],
)
@given(x=st.floats(-10.0, 10.0) | st.integers(-1, 6).map(float))
def test_level_forms_of_each_connective(condition, level, x):
    assert same_float(level_form(condition)((x, 0.0, 0.0, 0.0), {}), level(x))


def test_strict_comparisons_keep_their_strictness_inside_ite():
    assert ite(V.x > 0.0, 1.0, 2.0)((0.0,), {}) == 2.0
    assert ite(V.x >= 0.0, 1.0, 2.0)((0.0,), {}) == 1.0
    assert ite(~(V.x < 0.0), 1.0, 2.0)((0.0,), {}) == 1.0
    assert ite(Compare("!=", V.x, Const(0.0)), 1.0, 2.0)((0.0,), {}) == 2.0
    assert evaluate(ite(V.x > 0.0, 1.0, 2.0), (0.0,)) == 2.0


def test_not_equal_has_no_level_form():
    with pytest.raises(SymbolicError, match=r"!=.*no closed level form"):
        level_form(Compare("!=", V.x, Const(1.0)))
    with pytest.raises(SymbolicError, match="!="):
        level_form(~Compare("==", V.x, Const(1.0)))
    assert level_form(V.x) is V.x  # an expression is its own level form


# ============================================================================ error messages
POINT = (1.0, 2.0, 3.0, 0.0)


def assert_refused(make, *fragments):
    """An unsupported operation raises SymbolicError when built, or builds a placeholder refused when used.

    Either way the message contains every fragment (the operation, the operands, how to rewrite).
    """
    try:
        expr = make()
    except SymbolicError as err:
        message = str(err)
    else:
        with pytest.raises(SymbolicError) as compiled:
            expr(POINT, {"a": 1.0, "b": 1.0})
        with pytest.raises(SymbolicError) as interpreted:
            evaluate(expr, POINT, {"a": 1.0, "b": 1.0})
        assert str(compiled.value) == str(interpreted.value)
        message = str(compiled.value)
    for fragment in fragments:
        assert fragment in message, (fragment, message)
    return message


def test_division_by_a_non_constant_says_how_to_rewrite():
    assert_refused(lambda: V.x / V.y, "division by", "y", "multiply both sides", "ite(")
    assert_refused(lambda: V.x - 2.0 / (V.x + 1.0), "division by", "(x + 1)", "multiply")
    assert_refused(lambda: minimum(V.x / M.a, 1.0), "division by", "a", "multiply")
    assert_refused(lambda: V.x / 0.0, "division by", "0")
    assert_refused(lambda: V.x / param("zero", 0.0), "division by", "zero")
    for use in (lambda e: enclose(e, {"x": (0.0, 1.0)}), lambda e: diff(e, "x"), lambda e: level_form(e >= 1.0)(POINT, {})):
        with pytest.raises(SymbolicError, match="division by"):  # never an AttributeError from a placeholder
            use(V.x / V.y + 1.0)
    assert (V.x / param("two", 2.0))((3.0,), {}) == 1.5
    assert (V.x / 4)((3.0,), {}) == 0.75
    assert isinstance(SymbolicError("x"), ModelDefinitionError)


def test_python_truth_value_of_a_condition_and_builtins_are_refused():
    with pytest.raises(SymbolicError, match=r"ite\(\).*&|&.*ite\(\)") as info:
        bool(V.x > 1.0)
    assert "x > 1" in str(info.value)
    with pytest.raises(SymbolicError, match="ite"):
        if V.x > 1.0:
            pass
    with pytest.raises(SymbolicError, match="&, | and ~"):
        (V.x > 1.0) and (V.y > 2.0)  # noqa: B015
    with pytest.raises(SymbolicError, match="&, | and ~"):
        not (V.x > 1.0)  # noqa: B015
    with pytest.raises(SymbolicError):
        min(V.x, V.y)
    with pytest.raises(SymbolicError):
        max(V.x, V.y - 1.0)
    with pytest.raises(SymbolicError, match="evaluate"):
        float(V.x)
    with pytest.raises(SymbolicError, match="select"):
        [1.0, 2.0][V.x]
    with pytest.raises(SymbolicError, match="round"):
        round(V.x)
    with pytest.raises(SymbolicError, match="ite"):
        V.x + (V.y > 1.0)
    with pytest.raises(SymbolicError, match="bool"):
        V.x + True
    with pytest.raises(SymbolicError, match="unsupported operand"):
        V.x + "1"
    with pytest.raises(SymbolicError, match="not a symbolic condition"):
        (V.x > 1.0) & True
    with pytest.raises(SymbolicError, match="not a symbolic condition"):
        ite(V.x, 1.0, 2.0)


def test_powers_need_nonnegative_integer_exponents():
    for bad in (0.5, -1, 2.0, True):
        assert_refused(lambda: V.x ** bad, "power", repr(bad))
    assert_refused(lambda: V.x ** 0.5, "sqrt")
    assert_refused(lambda: 2.0 ** V.x, "exp(log(")
    assert (V.x ** 3)((2.0,), {}) == 8.0


def test_select_needs_options_and_an_index_in_range():
    with pytest.raises(SymbolicError, match="no options"):
        select(V.k, ())
    e = select(V.x, (1.0, 2.0))
    for bad in (-1.0, 2.0, 7.5, math.inf, math.nan):
        with pytest.raises(ExecutionError, match=r"outside -1 < index < 2.*2 option"):
            e((bad,), {})
        with pytest.raises(ExecutionError, match=r"outside -1 < index < 2"):
            evaluate(e, (bad,))
    assert e((-0.99,), {}) == 1.0 and e((1.99,), {}) == 2.0


def test_constants_and_names_are_validated():
    with pytest.raises(SymbolicError, match="NaN"):
        Const(math.nan)
    with pytest.raises(SymbolicError, match="bool"):
        Const(True)
    assert Const(math.inf).value == math.inf and Const(3).value == 3.0
    with pytest.raises(SymbolicError, match="finite"):
        param("p", math.inf)
    with pytest.raises(SymbolicError, match="identifier"):
        param("not a name", 1.0)
    with pytest.raises(SymbolicError, match="duplicate"):
        coordinates("x", "x")
    with pytest.raises(SymbolicError, match=r"no coordinate 'w'.*\['x', 'y', 'z', 'k'\]"):
        V.w
    with pytest.raises(SymbolicError, match="no memory variable 'c'"):
        M["c"]
    with pytest.raises(SymbolicError, match="at least one"):
        minimum()
    with pytest.raises(SymbolicError, match="at least one"):
        all_true()
    with pytest.raises(SymbolicError, match="at least one"):
        any_true()
    assert (Const(math.inf) + V.x)((1.0,), {}) == math.inf  # an infinite constant compiles to inf
    assert (Const(-math.inf) * V.x)((1.0,), {}) == -math.inf


def test_time_outside_flows_and_outputs_is_refused():
    """Compiled as ``lambda v, m: ... t ...``, time in a guard once raised NameError at the first call."""
    with pytest.raises(SymbolicError, match="time"):
        (V.x - time())((1.0,), {})
    with pytest.raises(SymbolicError, match="time"):
        reset(a=time())((1.0,), {})
    with pytest.raises(SymbolicError, match="time"):
        jump_map(time(), V.x)((1.0,), {})
    assert flow_map(time() * V.x)(2.0, (3.0,), {}) == (6.0,)
    assert output_map(time() + V.x)(2.0, (3.0,)) == (5.0,)


# ============================================================================ resets and maps
def test_symbolic_reset_returns_the_assigned_memory():
    r = reset(dL=V.x - M.a, n=M.b + 1.0)
    assert isinstance(r, SymbolicReset) and r.writes == ("dL", "n")
    got = r((4.0, 0.0, 0.0, 0.0), {"a": 1.5, "b": 2.0})
    assert got == {"dL": 2.5, "n": 3.0} and list(got) == ["dL", "n"]
    assert reset({"a": 1.0}, b=V.x)((7.0,), {}) == {"a": 1.0, "b": 7.0}
    assert reset()((), {}) == {}
    with pytest.raises(SymbolicError, match="memory name"):
        reset({"": V.x})
    with pytest.raises(SymbolicError, match="memory name"):
        SymbolicReset({3: V.x})
    with pytest.raises(TypeError):
        r.assignments["dL"] = V.y  # read-only


def test_jump_flow_and_output_maps_have_their_signatures():
    h, vel = coordinates("h", "v")
    m = memory("e")
    jump = jump_map(h, -m.e * vel)
    assert isinstance(jump, SymbolicVector) and len(jump) == 2
    assert jump((0.0, -3.0), {"e": 0.8}) == (0.0, 0.8 * 3.0)
    assert jump_map([h * 2.0])((1.5, 0.0), {}) == (3.0,)
    flow = flow_map(vel, -9.81 + 0.0 * time())
    assert flow(1.0, (2.0, 3.0), {}) == (3.0, -9.81)
    assert flow_map(time(), m.e)(0.25, (0.0, 0.0), {"e": 4.0}) == (0.25, 4.0)
    out = output_map(h + time(), vel * vel)
    assert out(0.5, (1.0, 3.0)) == (1.5, 9.0)
    with pytest.raises(TypeError):
        out(0.5, (1.0, 3.0), {})  # an output reads (t, x) only
    with pytest.raises(SymbolicError, match="memory"):
        output_map(h + m.e)
    with pytest.raises(SymbolicError, match="no components"):
        jump_map()
    with pytest.raises(SymbolicError, match="kind"):
        SymbolicVector((h,), "guard")
    with pytest.raises(SymbolicError, match="bool"):
        flow_map(True)


def test_structure_queries():
    e = ite(V.x > M.a, sin(V.y) * param("p", 1.5), sqrt(time() + exp(V.x)))
    syms = free_symbols(e)
    assert syms == {"coordinates": {"x", "y"}, "memory": {"a"}, "params": {"p"}, "time": {"t"}}
    assert transcendental_terms(e) == ["exp", "sin", "sqrt"]
    assert transcendental_terms(V.x * V.y) == []
    s = substitute(e, coordinates={"x": V.z + 1.0}, memory={"a": Const(0.5)}, params={"p": Const(2.0)})
    v = (0.0, 0.7, 0.3, 0.0)
    want = math.sin(0.7) * 2.0 if 0.3 + 1.0 > 0.5 else 0.0
    assert evaluate(s, v, {}) == want
    assert free_symbols(s)["coordinates"] == {"y", "z"} and free_symbols(s)["params"] == set()
    assert S.is_symbolic(e) and S.is_symbolic(V.x >= 1.0) and S.is_symbolic(reset(a=V.x))
    assert not S.is_symbolic(lambda v, m: 0.0)
    assert render((V.x >= 1.0) & ~(V.y < 2.0)) == "(x >= 1 and not (y < 2))"
    assert S.exact(0.1) == S.exact(0.1) and float(S.exact(0.1)) == 0.1


def test_a_compiled_function_shows_its_source_in_tracebacks():
    import linecache

    v = coordinates("x")
    fn = compiled_function(v.x - 1.0, "condition")
    assert linecache.getline(fn.__code__.co_filename, 1).strip() == "lambda v, m: (v[0] - 1.0)"


def test_enclose_with_a_shared_memo_gives_the_same_numbers():
    """``shared`` only skips re-enclosing a common subtree: the bounds equal the ones of separate calls."""
    import random

    from hybrid.symbolic import coordinates, cos, diff, enclose, sin

    x = coordinates("a", "b", "c")
    f = x.a * sin(x.b) * x.c - cos(x.a + 0.3 * x.b) * x.c ** 2
    entries = [diff(diff(f, u), w) for u in ("a", "b", "c") for w in ("a", "b", "c")] + [f]
    rng = random.Random(5)
    for _ in range(50):
        bounds = {}
        for name in ("a", "b", "c"):
            lo = rng.uniform(-2, 2)
            bounds[name] = (lo, lo + rng.choice([0.0, 1e-6, 0.3, 2.0]))
        shared: dict = {}
        assert [enclose(e, bounds, shared=shared) for e in entries] == [enclose(e, bounds) for e in entries]
        assert shared  # it was used
