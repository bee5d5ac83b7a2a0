"""The family generators, pure functions of (config, rng) -> (parts, params), and
``make_furniture``, which picks one by the config's type."""

from __future__ import annotations

import itertools
import math
from dataclasses import fields, replace
from typing import Any

import numpy as np

from stairenv.rotations import yaw_matrix
from stairenv.validation import check_choice
from stairenv.world.furniture.configs import (
    ArmchairConfig,
    BedConfig,
    BookshelfConfig,
    CabinetConfig,
    ChairConfig,
    LampConfig,
    SofaConfig,
    StoolConfig,
    TableConfig,
    WardrobeConfig,
    furniture_config,
)
from stairenv.world.furniture.fields import FurnitureConfig
from stairenv.world.furniture.model import FAMILIES, Furniture
from stairenv.world.furniture.parts import Part, cylinder_points, rot_y, rounded_bar_points


def _u(rng: np.random.Generator, r: tuple[float, float]) -> float:
    return float(rng.uniform(r[0], r[1]))


def _i(rng: np.random.Generator, r: tuple[int, int]) -> int:
    return int(rng.integers(r[0], r[1] + 1))

# --- builders (config, rng) -> (parts, params) ----------------------------------------------------
Built = tuple[list[Part], dict[str, Any]]


def _build_chair(c: ChairConfig, rng: np.random.Generator) -> Built:
    h, w, d = _u(rng, c.seat_height), _u(rng, c.seat_width), _u(rng, c.seat_depth)
    ts, lt = _u(rng, c.seat_thickness), _u(rng, c.leg_thickness)
    bh, bt = _u(rng, c.backrest_height), _u(rng, c.backrest_thickness)
    tilt = math.radians(_u(rng, c.backrest_tilt_deg))
    parts = [Part.from_bounds("seat", (-d / 2, -w / 2, h - ts), (d / 2, w / 2, h))]
    for sx, sy in itertools.product((1.0, -1.0), repeat=2):
        x0 = d / 2 - lt if sx > 0 else -d / 2
        y0 = w / 2 - lt if sy > 0 else -w / 2
        parts.append(Part.from_bounds("leg", (x0, y0, 0.0), (x0 + lt, y0 + lt, h - ts)))
    rot = rot_y(-tilt)  # the top leans back (towards -x)
    pivot = np.array([-d / 2 + bt / 2, 0.0, h])
    parts.append(Part.box("backrest", pivot + rot @ np.array([0.0, 0.0, bh / 2]), (bt / 2, w / 2, bh / 2), rot))
    return parts, {"seat_height": h, "seat_width": w, "seat_depth": d, "seat_thickness": ts,
                   "leg_thickness": lt, "backrest_height": bh, "backrest_tilt_deg": math.degrees(tilt)}


def _upholstered(label_seats: int, width_inner: float, arm_w: float, depth: float, back_t: float,
                 seat_h: float, cushion_t: float, leg_h: float, arm_h: float, back_h: float,
                 leg_t: float) -> list[Part]:
    """Armchair / sofa: legs, base, seat cushion(s), backrest over the full width, rounded armrests."""
    total_w = width_inner + 2.0 * arm_w
    xb, xf = -(depth + back_t) / 2, (depth + back_t) / 2
    parts = []
    for sx, sy in itertools.product((1.0, -1.0), repeat=2):
        x0 = xf - leg_t - 0.02 if sx > 0 else xb + 0.02
        y0 = total_w / 2 - leg_t - 0.02 if sy > 0 else -total_w / 2 + 0.02
        parts.append(Part.from_bounds("leg", (x0, y0, 0.0), (x0 + leg_t, y0 + leg_t, leg_h)))
    parts.append(Part.from_bounds("base", (xb + back_t, -width_inner / 2, leg_h),
                                  (xf, width_inner / 2, seat_h - cushion_t)))
    seat_w = width_inner / label_seats
    for k in range(label_seats):
        y0 = -width_inner / 2 + k * seat_w
        parts.append(Part.from_bounds("seat", (xb + back_t, y0, seat_h - cushion_t), (xf, y0 + seat_w, seat_h)))
    parts.append(Part.from_bounds("backrest", (xb, -total_w / 2, leg_h), (xb + back_t, total_w / 2, seat_h + back_h)))
    for side in (-1.0, 1.0):
        y_in, y_out = side * width_inner / 2, side * total_w / 2
        lo = (xb + back_t * 0.5, min(y_in, y_out), leg_h)
        hi = (xf, max(y_in, y_out), seat_h + arm_h)
        parts.append(Part.convex("armrest", rounded_bar_points(lo, hi, radius=0.5 * arm_w)))
    return parts


def _build_armchair(c: ArmchairConfig, rng: np.random.Generator) -> Built:
    h, w, d = _u(rng, c.seat_height), _u(rng, c.seat_width), _u(rng, c.seat_depth)
    ct, lh = _u(rng, c.cushion_thickness), _u(rng, c.leg_height)
    aw, ah = _u(rng, c.arm_width), _u(rng, c.arm_height)
    bt, bh = _u(rng, c.back_thickness), _u(rng, c.back_height)
    ct = min(ct, 0.5 * h)
    lh = min(lh, h - ct - 0.03)
    parts = _upholstered(1, w, aw, d, bt, h, ct, lh, ah, bh, 0.05)
    return parts, {"seat_height": h, "seat_width": w, "seat_depth": d, "cushion_thickness": ct,
                   "leg_height": lh, "arm_width": aw, "arm_height": ah, "back_height": bh}


def _build_sofa(c: SofaConfig, rng: np.random.Generator) -> Built:
    total, d, h = _u(rng, c.width), _u(rng, c.seat_depth), _u(rng, c.seat_height)
    ct, lh = _u(rng, c.cushion_thickness), _u(rng, c.leg_height)
    aw, ah = _u(rng, c.arm_width), _u(rng, c.arm_height)
    bt, bh = _u(rng, c.back_thickness), _u(rng, c.back_height)
    n = _i(rng, c.num_seats)
    aw = min(aw, 0.25 * total)
    ct = min(ct, 0.5 * h)
    lh = min(lh, h - ct - 0.03)
    parts = _upholstered(n, total - 2.0 * aw, aw, d, bt, h, ct, lh, ah, bh, 0.05)
    return parts, {"seat_height": h, "width": total, "seat_width": total - 2.0 * aw, "seat_depth": d,
                   "num_seats": n, "arm_height": ah, "back_height": bh}


def _build_stool(c: StoolConfig, rng: np.random.Generator) -> Built:
    h, r, ts, lt = _u(rng, c.seat_height), _u(rng, c.seat_radius), _u(rng, c.seat_thickness), _u(rng, c.leg_thickness)
    n = _i(rng, c.num_legs)
    is_round = bool(rng.uniform() < c.round_probability)
    if is_round:
        seat = Part.convex("seat", cylinder_points(r, h - ts, h))
    else:
        seat = Part.from_bounds("seat", (-r, -r, h - ts), (r, r, h))
    parts = [seat]
    leg_r = r - 0.75 * lt - 0.02  # leg centres this far from the axis (round seats)
    if not is_round and n == 4:
        leg_r *= math.sqrt(2.0)  # square seats: legs under the corners
    for k in range(n):
        a = 2.0 * math.pi * k / n + (math.pi / 4 if n == 4 else 0.0)
        center = (leg_r * math.cos(a), leg_r * math.sin(a), 0.5 * (h - ts))
        parts.append(Part.box("leg", center, (lt / 2, lt / 2, 0.5 * (h - ts)), yaw_matrix(a)))
    return parts, {"seat_height": h, "seat_radius": r, "num_legs": n, "round": is_round}


def _build_bed(c: BedConfig, rng: np.random.Generator) -> Built:
    double = c.size == "double"
    w = _u(rng, c.double_width if double else c.single_width)
    length, h = _u(rng, c.length), _u(rng, c.surface_height)
    mt, lh = _u(rng, c.mattress_thickness), _u(rng, c.leg_height)
    m, hh, ht = _u(rng, c.frame_margin), _u(rng, c.headboard_height), _u(rng, c.headboard_thickness)
    ph = _u(rng, c.pillow_height)
    footboard = bool(rng.uniform() < c.footboard_probability)
    mt = min(mt, 0.6 * h)
    lh = min(lh, h - mt - 0.03)
    hh = max(hh, h + 0.15)
    fw = w + 2.0 * m  # frame width
    x0 = 0.0
    parts = [Part.from_bounds("headboard", (x0, -fw / 2, 0.0), (x0 + ht, fw / 2, hh))]
    fx0, fx1 = x0 + ht, x0 + ht + length + 2.0 * m
    parts.append(Part.from_bounds("base", (fx0, -fw / 2, lh), (fx1, fw / 2, h - mt)))
    parts.append(Part.from_bounds("bed_surface", (fx0 + m, -w / 2, h - mt), (fx1 - m, w / 2, h)))
    for sx, sy in itertools.product((0, 1), repeat=2):
        lx = fx0 + 0.03 if sx == 0 else fx1 - 0.09
        ly = -fw / 2 + 0.03 if sy == 0 else fw / 2 - 0.09
        parts.append(Part.from_bounds("leg", (lx, ly, 0.0), (lx + 0.06, ly + 0.06, lh)))
    if footboard:
        top = h + float(rng.uniform(-0.05, 0.15))
        parts.append(Part.from_bounds("footboard", (fx1, -fw / 2, 0.0), (fx1 + 0.04, fw / 2, top)))
    n_pillows = 2 if double else 1
    pw = min(0.7, (w - 0.1) / n_pillows - 0.05)
    pd = float(rng.uniform(0.32, 0.42))
    for k in range(n_pillows):
        yc = 0.0 if n_pillows == 1 else (k - 0.5) * (w / 2)
        parts.append(Part.from_bounds("pillow", (fx0 + m + 0.04, yc - pw / 2, h),
                                      (fx0 + m + 0.04 + pd, yc + pw / 2, h + ph)))
    return parts, {"size": c.size, "width": w, "length": length, "surface_height": h,
                   "mattress_thickness": mt, "headboard_height": hh, "footboard": footboard}


def _build_table(c: TableConfig, rng: np.random.Generator) -> Built:
    h, tt = _u(rng, c.top_height), _u(rng, c.top_thickness)
    is_round = bool(rng.uniform() < c.round_probability)
    lt, inset = _u(rng, c.leg_thickness), _u(rng, c.leg_inset)
    if is_round:
        diameter = _u(rng, c.diameter)
        r = diameter / 2
        pole_r = max(0.04, 0.5 * lt + 0.02)
        base_r = min(0.6 * r, max(0.2, 0.35 * diameter))
        parts = [Part.convex("table_top", cylinder_points(r, h - tt, h)),
                 Part.convex("base", cylinder_points(base_r, 0.0, 0.03)),
                 Part.convex("pole", cylinder_points(pole_r, 0.03, h - tt))]
        return parts, {"top_height": h, "round": True, "diameter": diameter}
    d, length = _u(rng, c.depth), _u(rng, c.length)
    inset = min(inset, 0.25 * min(d, length))
    parts = [Part.from_bounds("table_top", (-d / 2, -length / 2, h - tt), (d / 2, length / 2, h))]
    for sx, sy in itertools.product((1.0, -1.0), repeat=2):
        x0 = d / 2 - inset - lt if sx > 0 else -d / 2 + inset
        y0 = length / 2 - inset - lt if sy > 0 else -length / 2 + inset
        parts.append(Part.from_bounds("leg", (x0, y0, 0.0), (x0 + lt, y0 + lt, h - tt)))
    return parts, {"top_height": h, "round": False, "depth": d, "length": length}


def _build_case(c: CabinetConfig, rng: np.random.Generator) -> Built:
    w, d, h = _u(rng, c.width), _u(rng, c.depth), _u(rng, c.height)
    ph, tt, dw = _u(rng, c.plinth_height), _u(rng, c.top_thickness), _u(rng, c.door_width)
    doors = max(1, round(w / dw))
    door_t = 0.02
    xb, xf = -d / 2, d / 2 - door_t
    parts = []
    if ph > 0.0:
        parts.append(Part.from_bounds("base", (xb, -w / 2 + 0.02, 0.0), (xf - 0.03, w / 2 - 0.02, ph)))
    parts.append(Part.from_bounds("body", (xb, -w / 2, ph), (xf, w / 2, h - tt)))
    parts.append(Part.from_bounds("top", (xb, -w / 2 - 0.01, h - tt), (d / 2 + 0.01, w / 2 + 0.01, h)))
    each = w / doors
    handle_z = min(0.5 * (ph + h - tt) + 0.15, 1.05) if h > 1.2 else h - tt - 0.1
    handles = []
    for k in range(doors):
        y0 = -w / 2 + k * each
        parts.append(Part.from_bounds("door", (xf, y0 + 0.002, ph + 0.005), (d / 2, y0 + each - 0.002, h - tt - 0.005)))
        # Handles sit next to the door's free edge (pairs of doors meet in the middle).
        right_hinged = (k % 2 == 0) if doors > 1 else True
        yh = y0 + each - 0.05 if right_hinged else y0 + 0.05
        handles.append(Part.from_bounds("handle", (d / 2, yh - 0.01, handle_z - 0.06), (d / 2 + 0.025, yh + 0.01, handle_z + 0.06)))
    parts.extend(handles)
    return parts, {"width": w, "depth": d, "height": h, "doors": doors}


def _build_bookshelf(c: BookshelfConfig, rng: np.random.Generator) -> Built:
    w, d, h = _u(rng, c.width), _u(rng, c.depth), _u(rng, c.height)
    t, n = _u(rng, c.board_thickness), _i(rng, c.num_shelves)
    back = 0.01
    n = max(1, min(n, int((h - t) / (0.15 + t))))
    parts = [Part.from_bounds("side", (-d / 2, -w / 2, 0.0), (d / 2, -w / 2 + t, h)),
             Part.from_bounds("side", (-d / 2, w / 2 - t, 0.0), (d / 2, w / 2, h)),
             Part.from_bounds("back", (-d / 2, -w / 2 + t, 0.0), (-d / 2 + back, w / 2 - t, h))]
    step = (h - t) / n
    inner = w - 2.0 * t
    books = []
    for k in range(n + 1):
        z = k * step
        parts.append(Part.from_bounds("shelf", (-d / 2 + back, -w / 2 + t, z), (d / 2, w / 2 - t, z + t)))
        if k < n and rng.uniform() < c.books_probability:
            gap = step - t
            bw = inner * float(rng.uniform(0.2, 0.7))
            bh = gap * float(rng.uniform(0.55, 0.85))
            bd = (d - back) * float(rng.uniform(0.6, 0.9))
            y0 = -w / 2 + t + float(rng.uniform(0.0, inner - bw))
            books.append(Part.from_bounds("books", (-d / 2 + back, y0, z + t), (-d / 2 + back + bd, y0 + bw, z + t + bh)))
    parts.extend(books)
    return parts, {"width": w, "depth": d, "height": h, "num_shelves": n, "shelf_heights": [k * step + t for k in range(n + 1)]}


def _build_lamp(c: LampConfig, rng: np.random.Generator) -> Built:
    h, br, bt = _u(rng, c.height), _u(rng, c.base_radius), _u(rng, c.base_thickness)
    pr, sr, taper, sh = _u(rng, c.pole_radius), _u(rng, c.shade_radius), _u(rng, c.shade_taper), _u(rng, c.shade_height)
    sh = min(sh, 0.5 * h)
    parts = [Part.convex("base", cylinder_points(br, 0.0, bt)),
             Part.convex("pole", cylinder_points(pr, bt, h - 0.5 * sh, segments=12)),
             Part.convex("lamp_shade", cylinder_points(sr, h - sh, h, top_radius=sr * taper))]
    return parts, {"height": h, "shade_radius": sr}

_BUILDERS: dict[type, Any] = {
    ChairConfig: _build_chair, ArmchairConfig: _build_armchair, StoolConfig: _build_stool,
    SofaConfig: _build_sofa, BedConfig: _build_bed, TableConfig: _build_table, CabinetConfig: _build_case,
    WardrobeConfig: _build_case, BookshelfConfig: _build_bookshelf, LampConfig: _build_lamp,
}

def make_furniture(family: str, rng: np.random.Generator, *, config: FurnitureConfig | None = None,
                   **overrides: Any) -> Furniture:
    """Sample one piece of ``family`` (see ``FAMILIES``) from its config with ``rng`` (pure).

    ``config`` replaces the family's default config (``FURNITURE_CONFIGS``); ``overrides``
    then change single fields: a (min, max) pair sets a range, a number fixes it, e.g.
    ``make_furniture("chair", rng, seat_height=0.45)``. Invalid values raise ``ValueError``
    naming the parameter and its valid range. A bed's family is "double_bed" when its
    ``size`` is "double" and "bed" otherwise.
    """
    check_choice("family", family, FAMILIES)
    if config is None:
        cfg = furniture_config(family, **overrides)
    else:
        names = [f.name for f in fields(config)]
        unknown = sorted(set(overrides) - set(names))
        if unknown:
            raise ValueError(f"{type(config).__name__} has no parameter(s) {unknown}; valid: {names}")
        cfg = replace(config, **overrides) if overrides else config
    builder = _BUILDERS.get(type(cfg))
    if builder is None:
        raise TypeError(f"config must be one of {[c.__name__ for c in _BUILDERS]}, got {type(cfg).__name__}")
    parts, params = builder(cfg, rng)
    if isinstance(cfg, BedConfig):
        family = "double_bed" if cfg.size == "double" else "bed"
    return Furniture.from_parts(family, parts, params)
