"""Collisions: ball and robots against the field walls and each other (impulses with restitution
and Coulomb friction, then a position projection out of penetration).

Shapes: the ball is a circle; a robot is a circle of radius R cut by a flat front (the dribbler /
kicker opening) at x = dribbler_offset - ball_radius in base_link; robots collide with each other
and with walls as plain circles. Walls are the field boundary walls at +-(half length + boundary)
and +-(half width + boundary); goals are not modelled as geometry.

Every impulse uses the pre-contact relative velocity, a restitution e <= 1 on the normal part (0 for
resting contact below 2 cm/s, so nothing jitters) and a tangential impulse cut at the sticking value
and at mu * normal impulse, so a collision never adds kinetic energy. Tangential impulses at the ball
act on its vertical spin wz (the contact is at the ball's equator). No rclpy import.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from erforce_interfaces.runtime.numba_support import numba
from erforce_interfaces.wire.robot_config import BALL_WALL_FRICTION, BALL_WALL_RESTITUTION, ROBOT_HEIGHT_M
from erforce_sim.ball import BallBody
from erforce_sim.drivetrain import RobotPlant

RESTING_SPEED_MPS = 0.02  # below this approach speed a contact is treated as resting (e = 0)


@dataclass(frozen=True)
class ContactParams:
    ball_wall_restitution: float = BALL_WALL_RESTITUTION
    ball_wall_friction: float = BALL_WALL_FRICTION
    ball_robot_restitution: float = 0.4
    ball_robot_friction: float = 0.3
    robot_wall_restitution: float = 0.2
    robot_wall_friction: float = 0.3
    robot_robot_restitution: float = 0.2
    robot_robot_friction: float = 0.3
    robot_height_m: float = ROBOT_HEIGHT_M  # a ball whose lowest point is higher flies over a robot

    def __post_init__(self) -> None:
        for name in self.__dataclass_fields__:
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f"ContactParams.{name}: must be finite and >= 0, got {v!r}")
            if name.endswith("restitution") and v > 1.0:
                raise ValueError(f"ContactParams.{name}: must be <= 1, got {v!r}")


@dataclass(frozen=True)
class RobotShape:
    """Robot outline in base_link: circle of radius_m with a flat front at x = front_x_m."""

    radius_m: float
    front_x_m: float

    def __post_init__(self) -> None:
        if not (0.0 < self.front_x_m < self.radius_m):
            raise ValueError(
                f"RobotShape: front face x ({self.front_x_m}) must lie inside the robot radius ({self.radius_m});"
                " check dribbler_offset_m and the ball radius"
            )

    @property
    def front_half_width_m(self) -> float:
        return math.sqrt(self.radius_m**2 - self.front_x_m**2)

    def closest_point(self, px: float, py: float) -> tuple[float, float, float, float, float]:
        """Signed distance from (px, py) (base_link) to the outline.

        Returns (distance, nx, ny, qx, qy): outward unit normal and the surface point; the distance is
        negative inside the robot.
        """
        rad, fx = self.radius_m, self.front_x_m
        hw = self.front_half_width_m
        d = math.hypot(px, py)
        if px <= fx and d <= rad:  # inside: leave through the nearer face
            depth_front = fx - px
            depth_round = rad - d
            if depth_front <= depth_round or d < 1e-12:
                return -depth_front, 1.0, 0.0, fx, py
            nx, ny = px / d, py / d
            return -depth_round, nx, ny, rad * nx, rad * ny
        if px > fx and abs(py) <= hw:  # in front of the flat face
            return px - fx, 1.0, 0.0, fx, py
        if d > 1e-12 and rad * px / d <= fx:  # the round part is nearest
            nx, ny = px / d, py / d
            return d - rad, nx, ny, rad * nx, rad * ny
        cy = hw if py > 0.0 else -hw  # a corner of the flat face
        dx, dy = px - fx, py - cy
        dist = math.hypot(dx, dy)
        if dist < 1e-12:
            return 0.0, 1.0, 0.0, fx, cy
        return dist, dx / dist, dy / dist, fx, cy


def _tangential_impulse(vt: float, k_t: float, jn: float, mu: float) -> float:
    jt = -vt / k_t
    lim = mu * jn
    if jt > lim:
        return lim
    if jt < -lim:
        return -lim
    return jt


def _restitution(vn: float, e: float) -> float:
    return e if -vn > RESTING_SPEED_MPS else 0.0


def _wall_impulse(vx: float, vy: float, w: float, nx: float, ny: float, radius: float, inv_m: float,
                  inertia: float, restitution: float, friction: float) -> tuple[float, float, float]:
    """(vx, vy, w) of a round body (ball or robot) after a wall's impulse, the wall's normal (nx, ny) pointing
    into the field and the body moving into the wall."""
    vn = vx * nx + vy * ny
    jn = -(1.0 + _restitution(vn, restitution)) * vn / inv_m
    tx, ty = -ny, nx
    # the contact point is at -radius n: its tangential velocity is v.t - radius w
    vt = vx * tx + vy * ty - radius * w
    jt = _tangential_impulse(vt, inv_m + radius * radius / inertia, jn, friction)
    return vx + (jn * nx + jt * tx) * inv_m, vy + (jn * ny + jt * ty) * inv_m, w - radius * jt / inertia


def _wall_contacts(x: float, y: float, radius: float, half_x: float, half_y: float):
    """Each wall a round body at (x, y) overlaps, in turn: the body's position put back inside the walls and
    the wall's normal (nx, ny) into the field."""
    for axis in (0, 1):
        lim = (half_x if axis == 0 else half_y) - radius
        pos = x if axis == 0 else y
        if -lim <= pos <= lim:
            continue
        sign = 1.0 if pos > lim else -1.0
        if axis == 0:
            x = sign * lim
            yield x, y, -sign, 0.0
        else:
            y = sign * lim
            yield x, y, 0.0, -sign


def ball_walls(ball: BallBody, half_x: float, half_y: float, p: ContactParams) -> bool:
    """Ball against the four walls. Returns True when a contact was resolved."""
    r = ball.radius
    hit = False
    for x, y, nx, ny in _wall_contacts(ball.x, ball.y, r, half_x, half_y):
        ball.x, ball.y = x, y
        hit = True
        if ball.vx * nx + ball.vy * ny >= 0.0:
            continue
        ball.vx, ball.vy, ball.wz = _wall_impulse(ball.vx, ball.vy, ball.wz, nx, ny, r, 1.0 / ball.mass, ball.inertia,
                                                  p.ball_wall_restitution, p.ball_wall_friction)
        ball.at_rest = False
    return hit


def robot_walls(rb: RobotPlant, radius: float, half_x: float, half_y: float, p: ContactParams) -> bool:
    hit = False
    k = rb.k
    for x, y, nx, ny in _wall_contacts(rb.x, rb.y, radius, half_x, half_y):
        rb.x, rb.y = x, y
        hit = True
        if rb.vx * nx + rb.vy * ny >= 0.0 or rb.lifted:
            continue
        rb.vx, rb.vy, rb.w = _wall_impulse(rb.vx, rb.vy, rb.w, nx, ny, radius, 1.0 / k.mass_kg, k.inertia_kgm2,
                                           p.robot_wall_restitution, p.robot_wall_friction)
    return hit


def robot_robot(a: RobotPlant, ra: float, b: RobotPlant, rb_: float, p: ContactParams) -> bool:
    dx, dy = b.x - a.x, b.y - a.y
    dmin = ra + rb_
    d2 = dx * dx + dy * dy
    if d2 >= dmin * dmin:
        return False
    d = math.sqrt(d2)
    if d < 1e-12:
        nx, ny, d = 1.0, 0.0, 0.0
    else:
        nx, ny = dx / d, dy / d
    inv_ma = 0.0 if a.lifted else 1.0 / a.k.mass_kg
    inv_mb = 0.0 if b.lifted else 1.0 / b.k.mass_kg
    inv_sum = inv_ma + inv_mb
    if inv_sum == 0.0:
        return True
    depth = dmin - d
    a.x -= nx * depth * inv_ma / inv_sum
    a.y -= ny * depth * inv_ma / inv_sum
    b.x += nx * depth * inv_mb / inv_sum
    b.y += ny * depth * inv_mb / inv_sum
    vn = (b.vx - a.vx) * nx + (b.vy - a.vy) * ny
    if vn >= 0.0:
        return True
    jn = -(1.0 + _restitution(vn, p.robot_robot_restitution)) * vn / inv_sum
    tx, ty = -ny, nx
    ia = 0.0 if a.lifted else 1.0 / a.k.inertia_kgm2
    ib = 0.0 if b.lifted else 1.0 / b.k.inertia_kgm2
    # contact points: a at +ra n, b at -rb n; tangential point velocities v.t + w (r x t)
    vt = (b.vx * tx + b.vy * ty - rb_ * b.w) - (a.vx * tx + a.vy * ty + ra * a.w)
    jt = _tangential_impulse(vt, inv_sum + ra * ra * ia + rb_ * rb_ * ib, jn, p.robot_robot_friction)
    jx, jy = jn * nx + jt * tx, jn * ny + jt * ty  # impulse on b; -impulse on a
    b.vx += jx * inv_mb
    b.vy += jy * inv_mb
    b.w -= rb_ * jt * ib
    a.vx -= jx * inv_ma
    a.vy -= jy * inv_ma
    a.w -= ra * jt * ia
    return True


def ball_robot(ball: BallBody, rb: RobotPlant, shape: RobotShape, p: ContactParams) -> bool:
    """Ball against one robot outline (a ball above the robot's height passes). Returns True when they touch."""
    if ball.z >= p.robot_height_m:
        return False
    dx, dy = ball.x - rb.x, ball.y - rb.y
    reach = shape.radius_m + ball.radius
    if dx * dx + dy * dy >= reach * reach:
        return False
    c, s = rb.cos_th, rb.sin_th
    px, py = c * dx + s * dy, -s * dx + c * dy
    dist, nxl, nyl, qxl, qyl = shape.closest_point(px, py)
    r = ball.radius
    if dist >= r:
        return False
    nx, ny = c * nxl - s * nyl, s * nxl + c * nyl  # outward normal, field frame
    qx, qy = c * qxl - s * qyl, s * qxl + c * qyl  # contact point relative to robot centre
    depth = r - dist
    ball.x += nx * depth
    ball.y += ny * depth
    # relative velocity of the ball's contact point (at -r n) against the robot's contact point
    pvx = rb.vx - rb.w * qy
    pvy = rb.vy + rb.w * qx
    vn = (ball.vx - pvx) * nx + (ball.vy - pvy) * ny
    if vn >= 0.0:
        return True
    k = rb.k
    inv_m = 1.0 / ball.mass
    if rb.lifted:
        inv_mr = inv_ir = 0.0
    else:
        inv_mr, inv_ir = 1.0 / k.mass_kg, 1.0 / k.inertia_kgm2
    qn = qx * ny - qy * nx
    jn = -(1.0 + _restitution(vn, p.ball_robot_restitution)) * vn / (inv_m + inv_mr + qn * qn * inv_ir)
    tx, ty = -ny, nx
    qt = qx * ty - qy * tx
    vt = (ball.vx - pvx) * tx + (ball.vy - pvy) * ty - r * ball.wz
    jt = _tangential_impulse(vt, inv_m + r * r / ball.inertia + inv_mr + qt * qt * inv_ir, jn, p.ball_robot_friction)
    jx, jy = jn * nx + jt * tx, jn * ny + jt * ty  # impulse on the ball
    ball.vx += jx * inv_m
    ball.vy += jy * inv_m
    ball.wz -= r * jt / ball.inertia
    ball.at_rest = False
    rb.vx -= jx * inv_mr
    rb.vy -= jy * inv_mr
    rb.w -= (qx * jy - qy * jx) * inv_ir
    return True


@numba.njit(cache=True, error_model="numpy")
def robot_contact_candidates(body, radii, front_x, half_x, half_y, margin, dt, bx, by, reach_b):
    """World._contact_candidates over the body rows (x, y, theta, cos, sin, vx, vy, w): robots near a wall,
    robots near the ball (flags) and the robot pairs that may touch within dt. A robot lies inside its circle
    and behind its flat front face, so the larger of the ball's distances to the two bounds it from below: a
    ball resting a little ahead of the front face (inside the circle) is no contact."""
    n = body.shape[0]
    wall = np.zeros(n, dtype=np.bool_)
    near = np.zeros(n, dtype=np.bool_)
    pairs = np.empty((n * (n - 1) // 2, 2), dtype=np.int64)
    count = 0
    speeds = np.empty(n)
    for a in range(n):
        speeds[a] = math.hypot(body[a, 5], body[a, 6])
    for a in range(n):
        xa, ya = body[a, 0], body[a, 1]
        reach = radii[a] + speeds[a] * dt + margin
        if abs(xa) + reach >= half_x or abs(ya) + reach >= half_y:
            wall[a] = True
        dx, dy = bx - xa, by - ya
        ahead = body[a, 3] * dx + body[a, 4] * dy - front_x[a]  # ball centre ahead of the front face [m]
        turn = abs(body[a, 7]) * radii[a] * dt  # how far the face's points move by turning within dt
        if max(math.hypot(dx, dy) - radii[a], ahead) <= reach - radii[a] + turn + reach_b:
            near[a] = True
        for b in range(a + 1, n):
            if math.hypot(body[b, 0] - xa, body[b, 1] - ya) <= reach + radii[b] + speeds[b] * dt:
                pairs[count, 0] = a
                pairs[count, 1] = b
                count += 1
    return wall, near, pairs[:count], count > 0 or wall.any() or near.any()
