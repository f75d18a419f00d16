"""Robot motion, camera projection, proximity and image measurements (floats only).

Everything here is on the per-sample path of the closed loop, which must run
in a few tens of microseconds: functions take and return Python floats and
tuples and use the :mod:`math` module only (a numpy call on a 3-vector costs
about a microsecond).  The kinematic *derivatives* (interaction rows, robot
Jacobian) are not re-typed here: they live in :mod:`visnav.model`.

Conventions (see ``docs/model.md``)
-----------------------------------
* World frame: ``x, y`` horizontal, heights up.  Robot state
  ``(x, y, theta, pan)``; pan centre ``P = M + Dx (cos theta, sin theta)``;
  camera heading ``phi = theta + pan``; optical centre
  ``C = P + a (cos phi, sin phi) + b (-sin phi, cos phi)`` at height
  ``camera_height_m``.
* Camera frame: ``z_C`` forward (optical axis), ``y_C`` left, ``x_C`` down.
  A world point ``(wx, wy, wh)`` has depth ``z = dx cos phi + dy sin phi``,
  ``y_c = -dx sin phi + dy cos phi``, ``x_c = camera_height - wh`` and
  normalised image coordinates ``X = x_c / z``, ``Y = y_c / z`` (``Y > 0`` to
  the left); pixels are ``focal_px`` times normalised coordinates.
* Bypass side ``side = +1``: the obstacle is kept on the robot's left
  (counter-clockwise bypass); ``-1``: on its right (clockwise).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from hybrid.errors import NumericalFailure
from visnav import model
from visnav.parameters import CameraModel, Obstacle, RobotGeometry

__all__ = [
    "SINC_SERIES_THRESHOLD",
    "TIE_TOLERANCE",
    "wrap_angle",
    "propagate_pose",
    "camera_pose",
    "project_point",
    "project_points",
    "nearest_obstacle",
    "choose_bypass_side",
    "Proximity",
    "proximity",
    "occluder_interval",
    "point_hidden",
    "ImageMeasurement",
    "image_measurement",
]

#: Below this ``|u|`` the function ``sin(u)/u`` is evaluated by its Taylor
#: series ``1 - u²/6 + u⁴/120`` (truncation error ``u⁶/5040 < 2e-28``).
SINC_SERIES_THRESHOLD = 1e-4

#: ``|cross(heading, c - M)|`` below which the obstacle counts as dead ahead.
TIE_TOLERANCE = 1e-12

_TWO_PI = 2.0 * math.pi
_INF = math.inf
_NAN = math.nan


def wrap_angle(angle: float) -> float:
    """Wrap an angle to ``(-pi, pi]`` [rad] (exact: uses ``math.remainder``)."""
    r = math.remainder(angle, _TWO_PI)
    if r <= -math.pi:
        r += _TWO_PI
    return r


def _sinc(u: float) -> float:
    """``sin(u)/u`` with the removable singularity at 0 (relative error ~1 ulp)."""
    if -SINC_SERIES_THRESHOLD < u < SINC_SERIES_THRESHOLD:
        u2 = u * u
        return 1.0 - u2 * (1.0 / 6.0 - u2 / 120.0)
    return math.sin(u) / u


def propagate_pose(
    pose: tuple[float, float, float, float], v: float, omega: float, pan_rate: float, dt: float
) -> tuple[float, float, float, float]:
    """Exact flow of the unicycle and pan platform under constant inputs.

    With ``h = omega dt`` the base travels the chord of its arc:
    ``Δx = v dt sinc(h/2) cos(theta + h/2)``, ``Δy = v dt sinc(h/2) sin(theta + h/2)``,
    which has no cancellation for any ``omega`` (``omega = 0`` gives the
    straight line).  ``theta`` and ``pan`` are not wrapped.

    Parameters
    ----------
    pose : tuple of 4 floats
        ``(x, y, theta, pan)`` [m, m, rad, rad].
    v, omega, pan_rate : float
        Constant inputs [m/s, rad/s, rad/s].
    dt : float
        Duration [s] (may be negative: the backward flow).
    """
    x, y, theta, pan = pose
    half = 0.5 * omega * dt
    chord = v * dt * _sinc(half)
    mid = theta + half
    return (x + chord * math.cos(mid), y + chord * math.sin(mid), theta + omega * dt, pan + pan_rate * dt)


def camera_pose(x: float, y: float, theta: float, pan: float, robot: RobotGeometry) -> tuple[float, float, float]:
    """Optical centre ``(cx, cy)`` [m] and camera heading ``phi = theta + pan`` [rad].

    :func:`visnav.model.camera_centre` (the single definition) with the robot's offsets.
    """
    return model.camera_centre(x, y, theta, pan, robot.pan_offset_m, robot.camera_forward_m,
                               robot.camera_lateral_m)


def _project_checked(
    cx: float, cy: float, phi: float, camera_height: float, wx: float, wy: float, wh: float, what: str
) -> tuple[float, float, float]:
    try:
        out = model.project_world_point(cx, cy, phi, camera_height, wx, wy, wh)
    except ZeroDivisionError:
        out = (_NAN, _NAN, 0.0)
    z = out[2]
    if not z > 0.0:
        raise NumericalFailure(
            f"{what} at ({wx:.6g}, {wy:.6g}, {wh:.6g}) has depth z = {z:.6g} m: "
            "expected z > 0 (the point is behind the camera)"
        )
    return out


def project_point(
    cx: float, cy: float, phi: float, camera_height: float, wx: float, wy: float, wh: float
) -> tuple[float, float, float]:
    """Normalised image coordinates and depth ``(X, Y, z)`` of one world point.

    :func:`visnav.model.project_world_point` (the single definition) with the check ``z > 0``.

    Raises
    ------
    NumericalFailure
        If the point is not in front of the camera (``z <= 0``).
    """
    return _project_checked(cx, cy, phi, camera_height, wx, wy, wh, "world point")


def project_points(
    cx: float,
    cy: float,
    phi: float,
    camera_height: float,
    points: tuple[tuple[float, float, float], ...],
) -> tuple[tuple[float, float, float], ...]:
    """:func:`project_point` for every point of ``points``; the error names the index."""
    return tuple(_project_checked(cx, cy, phi, camera_height, wx, wy, wh, f"point {i}")
                 for i, (wx, wy, wh) in enumerate(points))


# --------------------------------------------------------------------------- proximity


def nearest_obstacle(x: float, y: float, obstacles: tuple[Obstacle, ...]) -> tuple[int, float]:
    """Index of the obstacle nearest to ``M = (x, y)`` and ``d_coll = |M - c| - R`` [m].

    ``d_coll`` is the signed distance from M to the obstacle surface (negative
    inside).  Ties go to the lowest index; no obstacle gives ``(-1, inf)``.
    """
    best, best_d = -1, _INF
    for i, obs in enumerate(obstacles):
        ox, oy = obs.center_m
        d = math.hypot(x - ox, y - oy) - obs.radius_m
        if d < best_d:
            best, best_d = i, d
    return best, best_d


def choose_bypass_side(x: float, y: float, theta: float, obstacle: Obstacle) -> int:
    """Bypass side: ``+1`` (obstacle kept on the left) if its centre is left of the heading.

    An obstacle ahead-left is bypassed by swerving right, which keeps it on the
    robot's left: ``+1`` (counter-clockwise bypass).  Centre to the right gives
    ``-1``.  A centre on the heading line (``|cross| < TIE_TOLERANCE``) gives ``+1``.
    """
    ox, oy = obstacle.center_m
    cross = math.cos(theta) * (oy - y) - math.sin(theta) * (ox - x)
    return -1 if cross <= -TIE_TOLERANCE else 1


@dataclass(frozen=True, kw_only=True, slots=True)
class Proximity:
    """Path-frame description of the robot relative to one obstacle.

    Attributes
    ----------
    d_coll : float
        Signed distance from M to the obstacle surface [m].
    alpha : float
        Heading error relative to the travel tangent, in ``(-pi, pi]``; positive
        when the robot heads away from the obstacle [rad].
    rho : float
        Distance from M to the obstacle centre [m].
    curvature : float
        ``1/R`` of the obstacle [1/m].
    side : int
        Bypass side, ``+1`` (obstacle on the left) or ``-1``.

    With these definitions, for the unicycle, ``d(d_coll)/dt = v sin(alpha)``
    and ``d(alpha)/dt = -side omega + v cos(alpha) / rho``.
    """

    d_coll: float
    alpha: float
    rho: float
    curvature: float
    side: int


def _slot_setters(cls: type) -> tuple:
    """Slot setters of a frozen slots dataclass, in field order (fast construction).

    The generated ``__init__`` of a frozen dataclass sets every field through
    ``object.__setattr__``; the slot descriptors set them directly at a third
    of the cost, which matters on the per-sample path.  Only valid for
    classes without ``__post_init__`` (checked at import).
    """
    if hasattr(cls, "__post_init__"):
        raise TypeError(f"{cls.__name__} has __post_init__: fast construction would skip it")
    return tuple(cls.__dict__[name].__set__ for name in cls.__dataclass_fields__)


_new = object.__new__
_PROXIMITY_SETTERS = _slot_setters(Proximity)


def _make_proximity(d_coll: float, alpha: float, rho: float, curvature: float, side: int) -> Proximity:
    """``Proximity(...)`` without the frozen-``__init__`` overhead (positional, field order)."""
    obj = _new(Proximity)
    s_d, s_a, s_r, s_c, s_s = _PROXIMITY_SETTERS
    s_d(obj, d_coll)
    s_a(obj, alpha)
    s_r(obj, rho)
    s_c(obj, curvature)
    s_s(obj, side)
    return obj


def proximity(x: float, y: float, theta: float, obstacle: Obstacle, side: int) -> Proximity:
    """Proximity data ``(d_coll, alpha)`` of ``M = (x, y)``, heading ``theta``, for a bypass side.

    ``e_r = (M - c)/rho``; travel tangent ``t = side * rot90(e_r)``;
    ``alpha = -side * wrap(theta - atan2(t))``.

    Raises
    ------
    NumericalFailure
        If M is at the obstacle centre (the path frame is undefined).
    """
    ox, oy = obstacle.center_m
    ex, ey = x - ox, y - oy
    rho = math.hypot(ex, ey)
    if not rho > 0.0:
        raise NumericalFailure(
            f"robot reference point at the centre of obstacle {obstacle.name!r}: rho = {rho!r} m, "
            "the path frame is undefined (expected rho > 0)"
        )
    # t = side * (-e_y, e_x); atan2 is scale-invariant so e_r need not be normalised.
    theta_t = math.atan2(side * ex, -side * ey)
    alpha = -side * wrap_angle(theta - theta_t)
    return _make_proximity(rho - obstacle.radius_m, alpha, rho, 1.0 / obstacle.radius_m, side)


# --------------------------------------------------------------------------- image measurements


def occluder_interval(
    cx: float, cy: float, phi: float, obstacle: Obstacle
) -> tuple[float, float, float, float] | None:
    """Image interval ``(Y_minus, Y_plus, z_minus, z_plus)`` subtended by a tall obstacle.

    The two tangent rays from C make the angles ``beta_c ± asin(R/dist)`` with
    the optical axis (``beta_c``: bearing of the centre).  ``Y± = tan`` of these
    angles and ``z±`` are the depths of the tangent points; by the envelope
    theorem a border moves in the image like its tangent point held fixed.
    Computed without trigonometry: with the centre at ``(z_o, y_o)`` in the
    camera frame, ``dist² = z_o² + y_o²`` and ``L = sqrt(dist² - R²)``,
    ``Y± = (y_o L ± z_o R) / (z_o L ∓ y_o R)`` and ``z± = L (z_o L ∓ y_o R) / dist²``.

    Returns ``None`` if C is inside or on the circle, or if a tangent ray is
    not strictly in front of the camera (bearing outside ``(-pi/2, pi/2)``).
    The interval is not clipped to the image.
    """
    ox, oy = obstacle.center_m
    c, s = math.cos(phi), math.sin(phi)
    dx, dy = ox - cx, oy - cy
    return _interval(dx * c + dy * s, dy * c - dx * s, dx * dx + dy * dy, obstacle.radius_m)


def _interval(zo: float, yo: float, dist2: float, r: float) -> tuple[float, float, float, float] | None:
    """Kernel of :func:`occluder_interval`: centre at ``(z_o, y_o)`` in the camera frame."""
    tan2 = dist2 - r * r
    if not tan2 > 0.0:
        return None
    ell = math.sqrt(tan2)
    fwd_minus = zo * ell + yo * r
    fwd_plus = zo * ell - yo * r
    if not (fwd_minus > 0.0 and fwd_plus > 0.0):
        return None
    k = ell / dist2
    return (
        (yo * ell - zo * r) / fwd_minus,
        (yo * ell + zo * r) / fwd_plus,
        k * fwd_minus,
        k * fwd_plus,
    )


def point_hidden(cx: float, cy: float, wx: float, wy: float, obstacle: Obstacle) -> bool:
    """Whether the horizontal segment ``C -> W`` meets the closed disc of ``obstacle``.

    Exact test on the closest point of the segment to the centre.  The height
    of the point is irrelevant: callers apply it to tall obstacles only.
    """
    ox, oy = obstacle.center_m
    r = obstacle.radius_m
    return _segment_meets_disc(wx - cx, wy - cy, ox - cx, oy - cy, r * r)


def _segment_meets_disc(sx: float, sy: float, px: float, py: float, r2: float) -> bool:
    """Segment from the origin to ``(sx, sy)`` against the disc of centre ``(px, py)``."""
    ss = sx * sx + sy * sy
    ps = px * sx + py * sy
    if ps <= 0.0 or ss == 0.0:
        return px * px + py * py <= r2
    if ps >= ss:
        ex, ey = px - sx, py - sy
        return ex * ex + ey * ey <= r2
    # perpendicular distance² = |p|² - (p·s)²/|s|²
    return px * px + py * py - ps * ps / ss <= r2


@dataclass(frozen=True, kw_only=True, slots=True)
class ImageMeasurement:
    """What the image processing extracts at one sample.

    Attributes
    ----------
    in_view : tuple of bool
        Per point: ``z > 0``, ``|X| <= x_limit`` and ``|Y| <= y_limit``.
    occluded : tuple of bool
        Per point: hidden by some tall obstacle (segment ``C -> W`` meets it).
    visible : tuple of bool
        ``in_view and not occluded``.
    occluder_index : int
        Index (in the obstacle tuple) of the tall obstacle in front with the
        smallest ``d_occ``; ``-1`` if none.
    y_o_minus, y_o_plus, z_o_minus, z_o_plus : float
        Its silhouette borders (normalised) and tangent-point depths [m];
        ``nan`` when there is no occluder.
    d_occ_px : float
        Distance before occlusion [px]: ``f min |Y_j - Y_b|`` over visible
        features ``j`` and both borders ``b``; ``0`` if a feature is hidden by
        the occluder; ``+inf`` without occluder or visible feature.
    d_bord_px : float
        Distance from the occluder border on the features' side to the image
        side opposite the features [px], ``>= 0``; ``+inf`` without occluder.
    feature_side : int
        ``+1`` if the features lie on the left (``+Y``) side of the silhouette
        centre, ``-1`` on the right, ``0`` without occluder.
    nearest_feature : int
        The feature ``j`` realising ``d_occ`` (``-1`` if ``d_occ`` is infinite).
    occ_border : int
        ``+1`` if ``Y_occ = y_o_plus``, ``-1`` if ``Y_occ = y_o_minus``, ``0`` if none.
    occ_sign : int
        Sign of ``Y_j - Y_occ`` for the nearest feature on the free side
        (``d_occ = occ_sign f (Y_j - Y_occ)`` near the current configuration).
    """

    in_view: tuple[bool, ...]
    occluded: tuple[bool, ...]
    visible: tuple[bool, ...]
    occluder_index: int
    y_o_minus: float
    y_o_plus: float
    z_o_minus: float
    z_o_plus: float
    d_occ_px: float
    d_bord_px: float
    feature_side: int
    nearest_feature: int
    occ_border: int
    occ_sign: int


_MEASUREMENT_SETTERS = _slot_setters(ImageMeasurement)


def _make_measurement(
    in_view,
    occluded,
    visible,
    occluder_index,
    y_o_minus,
    y_o_plus,
    z_o_minus,
    z_o_plus,
    d_occ_px,
    d_bord_px,
    feature_side,
    nearest_feature,
    occ_border,
    occ_sign,
) -> ImageMeasurement:
    """``ImageMeasurement(...)`` from positional values in field order, without ``__init__`` overhead."""
    obj = _new(ImageMeasurement)
    (
        set_in_view,
        set_occluded,
        set_visible,
        set_occluder_index,
        set_y_o_minus,
        set_y_o_plus,
        set_z_o_minus,
        set_z_o_plus,
        set_d_occ_px,
        set_d_bord_px,
        set_feature_side,
        set_nearest_feature,
        set_occ_border,
        set_occ_sign,
    ) = _MEASUREMENT_SETTERS
    set_in_view(obj, in_view)
    set_occluded(obj, occluded)
    set_visible(obj, visible)
    set_occluder_index(obj, occluder_index)
    set_y_o_minus(obj, y_o_minus)
    set_y_o_plus(obj, y_o_plus)
    set_z_o_minus(obj, z_o_minus)
    set_z_o_plus(obj, z_o_plus)
    set_d_occ_px(obj, d_occ_px)
    set_d_bord_px(obj, d_bord_px)
    set_feature_side(obj, feature_side)
    set_nearest_feature(obj, nearest_feature)
    set_occ_border(obj, occ_border)
    set_occ_sign(obj, occ_sign)
    return obj


def image_measurement(
    cam_pose: tuple[float, float, float],
    camera_height: float,
    features: tuple[tuple[float, float, float], ...],
    world_points: tuple[tuple[float, float, float], ...],
    obstacles: tuple[Obstacle, ...],
    camera: CameraModel,
    occluding: tuple[bool, ...] | None = None,
) -> ImageMeasurement:
    """Visibility flags and the occlusion distances ``d_occ``, ``d_bord`` of one image.

    Parameters
    ----------
    cam_pose : tuple
        ``(cx, cy, phi)`` from :func:`camera_pose`.
    camera_height : float
        Height of the optical centre [m].
    features : tuple of (X, Y, z)
        One per world point.  For points in view these are the measured
        projections; for hidden points the caller may pass reconstructed
        values (they enter only the mean that decides ``feature_side`` and,
        when hidden by the occluder, the choice of the feature to push out).
    world_points : tuple of (wx, wy, wh)
        The target points (used for the exact occlusion test).
    obstacles : tuple of Obstacle
    camera : CameraModel
    occluding : tuple of bool, optional
        Per obstacle, whether it is tall enough to occlude; computed with
        :meth:`Obstacle.occludes` when omitted (pass it to save time).

    Notes
    -----
    Answers to the paper's open questions 9 and 10 (see ``docs/model.md``):
    ``d_bord`` follows the text (occluder to the image side *opposite* the
    features); ``d_occ`` is ``0`` while a feature is hidden by the occluder and
    ``+inf`` when no occluder is in front.
    """
    cx, cy, phi = cam_pose
    n = len(features)
    if len(world_points) != n or n == 0:
        raise ValueError(
            f"image_measurement: {n} features and {len(world_points)} world points "
            "(expected one feature per point, at least one point)"
        )
    if occluding is None:
        occluding = tuple(o.occludes(camera_height) for o in obstacles)
    c, s = math.cos(phi), math.sin(phi)
    x_lim, y_lim, f = camera.x_limit, camera.y_limit, camera.focal_px
    in_view = tuple([z > 0.0 and -x_lim <= xx <= x_lim and -y_lim <= yy <= y_lim for xx, yy, z in features])

    occluded, tall = _occlusions(cx, cy, world_points, obstacles, occluding)
    if True in occluded:
        visible = tuple([iv and not oc for iv, oc in zip(in_view, occluded)])
    else:
        visible = in_view

    best = _occluder(tall, features, visible, c, s, f)
    if best is None:
        return _make_measurement(
            in_view, tuple(occluded), visible, -1, _NAN, _NAN, _NAN, _NAN, _INF, _INF, 0, -1, 0, 0
        )
    d_occ, k, (y_minus, y_plus, z_minus, z_plus), side, nearest, border, sign = best
    if side > 0:
        d_bord = f * (y_plus + y_lim)
    else:
        d_bord = f * (y_lim - y_minus)
    if d_bord < 0.0:
        d_bord = 0.0
    return _make_measurement(
        in_view, tuple(occluded), visible, k, y_minus, y_plus, z_minus, z_plus, d_occ, d_bord, side, nearest,
        border, sign,
    )


def _occlusions(
    cx: float, cy: float, world_points: tuple[tuple[float, float, float], ...], obstacles: tuple[Obstacle, ...],
    occluding: tuple[bool, ...],
) -> tuple[list[bool], list[tuple[int, float, float, float, float, list[bool]]]]:
    """The exact occlusion test of :func:`image_measurement`: per world point, whether a tall obstacle hides it
    from the optical centre ``(cx, cy)``; and per tall obstacle ``(index, px, py, |p|^2, radius, hidden points)``
    with ``p`` its centre relative to the optical centre [m]."""
    n = len(world_points)
    occluded = [False] * n
    tall = []
    rel = None
    for k, obs in enumerate(obstacles):
        if not occluding[k]:
            continue
        if rel is None:
            rel = []
            for wx, wy, _ in world_points:
                sx, sy = wx - cx, wy - cy
                rel.append((sx, sy, sx * sx + sy * sy))
        ox, oy = obs.center_m
        px, py = ox - cx, oy - cy
        r = obs.radius_m
        r2 = r * r
        pp = px * px + py * py
        hidden = []
        for j, (sx, sy, ss) in enumerate(rel):
            # closest point of the segment C -> W_j to the centre (see _segment_meets_disc)
            ps = px * sx + py * sy
            if ps <= 0.0 or ss == 0.0:
                h = pp <= r2
            elif ps >= ss:
                ex, ey = px - sx, py - sy
                h = ex * ex + ey * ey <= r2
            else:
                h = pp - ps * ps / ss <= r2
            if h:
                occluded[j] = True
            hidden.append(h)
        tall.append((k, px, py, pp, r, hidden))
    return occluded, tall


def _occluder(
    tall: list[tuple[int, float, float, float, float, list[bool]]], features: tuple[tuple[float, float, float], ...],
    visible: tuple[bool, ...], c: float, s: float, f: float,
) -> tuple | None:
    """The occluder of :func:`image_measurement`: the tall obstacle in front with the smallest ``d_occ``, as
    ``(d_occ, index, interval, side, nearest, border, sign)``; ``None`` when none is in front. ``c``, ``s``: cosine
    and sine of the camera's heading; ``f``: focal length [px]."""
    n = len(features)
    best = None  # (d_occ, k, interval, side, nearest, border, sign)
    if tall:
        ys = [ft[1] for ft in features]
        mean_y = sum(ys) / n
    for k, px, py, pp, r, hidden in tall:
        interval = _interval(px * c + py * s, py * c - px * s, pp, r)
        if interval is None:
            continue
        y_minus, y_plus = interval[0], interval[1]
        side = 1 if mean_y >= 0.5 * (y_minus + y_plus) else -1
        if True in hidden:
            # A feature hidden by this occluder: d_occ = 0.  The feature to push
            # out (through the border on the features' side) is the deepest one.
            y_b = y_plus if side > 0 else y_minus
            nearest, depth = -1, -_INF
            for j in range(n):
                if hidden[j] and side * (y_b - ys[j]) > depth:
                    nearest, depth = j, side * (y_b - ys[j])
            cand = (0.0, k, interval, side, nearest, side, side)
        else:
            d, nearest, border, sign = _INF, -1, 0, 0
            for j in range(n):
                if not visible[j]:
                    continue
                dp, dm = ys[j] - y_plus, ys[j] - y_minus
                adp, adm = abs(dp), abs(dm)
                if adp <= adm:
                    if adp < d:
                        d, nearest, border, sign = adp, j, 1, (1 if dp >= 0.0 else -1)
                elif adm < d:
                    d, nearest, border, sign = adm, j, -1, (1 if dm >= 0.0 else -1)
            cand = (f * d, k, interval, side, nearest, border, sign)
        if best is None or cand[0] < best[0]:
            best = cand
    return best
