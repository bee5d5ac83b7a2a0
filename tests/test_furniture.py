"""Parametric furniture and rooms (``stairenv.world.furniture``, ``stairenv.world.rooms``):
families, labelled convex parts, contact surfaces and nearest points, collision in MuJoCo
(a ball dropped on a seat rests on it, one dropped between a chair's legs reaches the floor),
room and house generation (no overlaps, inside the walls, connected free space, requested
categories, layout graphs) and compiling everything with the humanoid."""

from __future__ import annotations

import math
from collections import Counter

import mujoco
import numpy as np
import pytest
from scipy import ndimage

from stairenv.humanoid import load_humanoid_spec
from stairenv.world.furniture import (
    FAMILIES,
    ChairConfig,
    Furniture,
    Part,
    PlacedFurniture,
    add_furniture_to_spec,
    furniture_config,
    make_furniture,
)
from stairenv.world.rooms import (
    Door,
    Room,
    RoomConfig,
    add_room_to_spec,
    footprint_distance,
    generate_house,
    generate_room,
)
from stairenv.world.rooms.graph import segment_hits_box
from stairenv.world.scenes import Box

SEEDS = (0, 1, 2, 3)
EXPECTED_LABELS = {
    "chair": {"seat", "backrest", "leg"},
    "armchair": {"seat", "backrest", "armrest", "base", "leg"},
    "stool": {"seat", "leg"},
    "sofa": {"seat", "backrest", "armrest", "base", "leg"},
    "bed": {"bed_surface", "headboard", "pillow", "base", "leg"},
    "double_bed": {"bed_surface", "headboard", "pillow", "base", "leg"},
    "table": {"table_top"},
    "cabinet": {"body", "door", "handle", "top"},
    "wardrobe": {"body", "door", "handle", "top"},
    "bookshelf": {"shelf", "side", "back"},
    "lamp": {"base", "pole", "lamp_shade"},
}
SEAT_FAMILIES = ("chair", "armchair", "sofa", "stool")
BALL_RADIUS = 0.05


def _make(family: str, seed: int, **overrides) -> Furniture:
    return make_furniture(family, np.random.default_rng(seed), **overrides)


# --- furniture -------------------------------------------------------------------------------------
@pytest.mark.parametrize("family", FAMILIES)
def test_every_family_builds_with_labelled_convex_parts_in_its_frame(family):
    for seed in SEEDS:
        f = _make(family, seed)
        assert f.family == family and f.category == family
        assert EXPECTED_LABELS[family] <= set(f.labels)
        assert all(p.label in f.labels for p in f.parts())
        lo, hi = f.bounds
        assert lo[2] == pytest.approx(0.0, abs=1e-9)  # stands on the floor
        assert (lo[:2] + hi[:2]) == pytest.approx([0.0, 0.0], abs=1e-9)  # footprint centred
        assert f.footprint == pytest.approx(0.5 * (hi[:2] - lo[:2]))
        assert f.height == pytest.approx(hi[2])
        assert 0.1 < f.height < 2.5 and 0.05 < min(f.footprint) and max(f.footprint) < 1.6
        for part in f.parts():
            mesh = part.mesh()
            assert mesh.is_convex and mesh.is_watertight, (family, part.label)
            assert mesh.volume > 0.0
        if family in ("table",):
            assert set(f.labels) & {"leg", "pole"}


def test_human_scale_dimensions():
    for seed in SEEDS:
        for family in SEAT_FAMILIES:
            f = _make(family, seed)
            top = f.contact_surface("seat").center[2]
            assert 0.42 <= top <= 0.50 and top == pytest.approx(f.params["seat_height"])
        for family in ("bed", "double_bed"):
            f = _make(family, seed)
            top = f.contact_surface("bed_surface").center[2]
            assert 0.45 <= top <= 0.60 and top == pytest.approx(f.params["surface_height"])
            width = 2 * f.contact_surface("bed_surface").half_extents.min()
            assert (0.9 <= width <= 1.2) if family == "bed" else (1.4 <= width <= 1.8)
            assert 1.9 <= 2 * f.contact_surface("bed_surface").half_extents.max() <= 2.2
        table = _make("table", seed)
        assert 0.72 <= table.contact_surface("table_top").center[2] <= 0.78
        assert 1.8 <= _make("wardrobe", seed).height <= 2.2
        assert 1.4 <= _make("lamp", seed).height <= 1.8


def test_front_faces_plus_x():
    for seed in SEEDS:
        chair = _make("chair", seed)
        assert chair.parts("backrest")[0].center[0] < chair.contact_surface("seat").center[0]
        sofa = _make("sofa", seed)
        assert sofa.parts("backrest")[0].center[0] < sofa.contact_surface("seat").center[0]
        bed = _make("bed", seed)
        assert bed.parts("headboard")[0].center[0] < bed.contact_surface("bed_surface").center[0]
        wardrobe = _make("wardrobe", seed)
        assert min(d.center[0] for d in wardrobe.parts("door")) > wardrobe.parts("body")[0].center[0]


def test_make_furniture_is_pure_and_seeds_differ():
    for family in FAMILIES:
        a, b = _make(family, 7), _make(family, 7)
        assert [p.label for p in a.parts()] == [p.label for p in b.parts()]
        assert all(np.array_equal(p.vertices, q.vertices) for p, q in zip(a.parts(), b.parts()))
        c = _make(family, 8)
        assert a.footprint != c.footprint or a.height != c.height


def test_configs_validate_and_overrides_apply():
    with pytest.raises(ValueError, match=r"seat_height must lie within \[0\.25, 0\.9\]"):
        ChairConfig(seat_height=(0.1, 0.2))
    with pytest.raises(ValueError, match="seat_height"):
        make_furniture("chair", np.random.default_rng(0), seat_height=1.5)
    with pytest.raises(ValueError, match=r"num_legs must be a \(min, max\) pair of integers"):
        make_furniture("stool", np.random.default_rng(0), num_legs=(3.5, 4))
    with pytest.raises(ValueError, match="no parameter"):
        make_furniture("chair", np.random.default_rng(0), wings=2)
    with pytest.raises(ValueError, match="family must be one of"):
        make_furniture("throne", np.random.default_rng(0))
    with pytest.raises(ValueError, match="size must be one of"):
        furniture_config("bed", size="king")
    chair = _make("chair", 0, seat_height=0.47)
    assert chair.contact_surface("seat").center[2] == pytest.approx(0.47)
    assert _make("bed", 0, size="double").family == "double_bed"
    assert _make("stool", 0, num_legs=4).params["num_legs"] == 4
    assert len(_make("stool", 0, num_legs=3).parts("leg")) == 3


def test_nearest_point_on_box_parts():
    rng = np.random.default_rng(0)
    # An axis-aligned box: the nearest point is the clipped point.
    part = Part.from_bounds("seat", (-0.2, -0.25, 0.4), (0.2, 0.25, 0.45))
    points = rng.uniform(-1.0, 1.0, size=(200, 3)) + [0.0, 0.0, 0.4]
    expected = np.clip(points, [-0.2, -0.25, 0.4], [0.2, 0.25, 0.45])
    assert part.nearest_point(points) == pytest.approx(expected, abs=1e-12)
    inside = np.array([[0.05, -0.1, 0.42]])
    assert part.nearest_point(inside) == pytest.approx(inside)
    # A rotated box (a tilted backrest): the box formula agrees with the exact point-to-triangle
    # search on the same solid given as a convex mesh.
    chair = _make("chair", 3, backrest_tilt_deg=20.0)
    back = chair.parts("backrest")[0]
    assert back.is_box and not np.allclose(back.rotation, np.eye(3))
    as_mesh = Part.convex("backrest", back.vertices)
    points = rng.uniform(-1.0, 1.0, size=(300, 3)) + back.center
    got = back.nearest_point(points)
    assert got == pytest.approx(as_mesh.nearest_point(points), abs=1e-9)
    assert np.all(back.contains(got, tol=1e-9))
    # Furniture.nearest_point over all parts of a label, and in the world for a placed piece.
    seat_top = chair.contact_surface("seat").center
    query = seat_top + [0.0, 0.0, 0.3]
    assert chair.nearest_point("seat", query) == pytest.approx(seat_top)
    placed = PlacedFurniture("chair_0", chair, (1.5, -2.0, 0.8))
    world_query = placed.to_world(query)
    assert placed.nearest_point("seat", world_query) == pytest.approx(placed.to_world(seat_top))
    legs = chair.nearest_point("leg", np.array([[5.0, 5.0, 0.1], [-5.0, -5.0, 0.1]]))
    leg_vertices = np.concatenate([p.vertices for p in chair.parts("leg")])
    assert legs[0, :2] == pytest.approx(leg_vertices.max(axis=0)[:2])  # the outer corners of two legs
    assert legs[1, :2] == pytest.approx(leg_vertices.min(axis=0)[:2])


def test_nearest_point_on_mesh_parts_lies_on_the_part():
    lamp = _make("lamp", 0)
    rng = np.random.default_rng(1)
    points = rng.uniform(-1.0, 1.0, size=(100, 3)) + [0.0, 0.0, 1.0]
    near = lamp.nearest_point("lamp_shade", points)
    shade = lamp.parts("lamp_shade")[0]
    assert np.all(shade.contains(near, tol=1e-9))
    dist = np.linalg.norm(near - points, axis=1)
    # No vertex of the part is closer than the returned point.
    vert = np.min(np.linalg.norm(points[:, None] - shade.vertices[None], axis=-1), axis=1)
    assert np.all(dist <= vert + 1e-12)


def test_contact_surfaces():
    sofa = _make("sofa", 0, num_seats=3)
    seat = sofa.contact_surface("seat")  # three cushions merged into one rectangle
    assert len(sofa.parts("seat")) == 3
    assert seat.normal == pytest.approx([0.0, 0.0, 1.0])
    assert 2 * max(seat.half_extents) == pytest.approx(sofa.params["seat_width"])
    with pytest.raises(ValueError, match="pass index"):
        sofa.contact_surface("armrest")
    left, right = sofa.contact_surface("armrest", 0), sofa.contact_surface("armrest", 1)
    assert left.center[2] == pytest.approx(right.center[2]) and left.center[2] > seat.center[2]
    back = _make("chair", 0).contact_surface("backrest")
    assert back.normal[0] > 0.9  # the backrest's front
    shelf = _make("bookshelf", 0)
    heights = [shelf.contact_surface("shelf", k).center[2] for k in range(len(shelf.parts("shelf")))]
    assert heights == sorted(heights)
    with pytest.raises(KeyError, match="no part labelled"):
        shelf.contact_surface("seat")
    points = seat.sample(np.random.default_rng(0), 20, margin=0.05)
    assert np.all(np.abs(points[:, 2] - seat.center[2]) < 1e-9)


def test_mesh_export():
    for family in ("armchair", "lamp", "bookshelf"):
        f = _make(family, 0)
        mesh = f.mesh()
        assert len(mesh.faces) == sum(len(p.mesh().faces) for p in f.parts())
        assert len(f.scene().geometry) == len(f.parts())


# --- collision in MuJoCo ---------------------------------------------------------------------------
def _drop_ball(furniture: Furniture, pose, start: np.ndarray, seconds: float = 1.2) -> np.ndarray:
    spec = mujoco.MjSpec()
    spec.option.timestep = 0.002
    spec.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.1])
    handle = add_furniture_to_spec(spec, furniture, pose, name="piece")
    ball = spec.worldbody.add_body(name="ball", pos=list(start))
    ball.add_freejoint()
    ball.add_geom(name="ball", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[BALL_RADIUS, 0, 0], density=300)
    model = spec.compile()
    handle.bind(model)
    for label, ids in handle.geom_ids.items():
        assert len(ids) == len(furniture.parts(label))
    data = mujoco.MjData(model)
    for _ in range(int(seconds / model.opt.timestep)):
        mujoco.mj_step(model, data)
    assert np.linalg.norm(data.qvel) < 1e-2  # at rest
    return data.qpos[:3].copy()


@pytest.mark.parametrize("family,label", [*[(f, "seat") for f in SEAT_FAMILIES], ("bed", "bed_surface"),
                                          ("double_bed", "bed_surface"), ("table", "table_top")])
def test_ball_rests_on_the_surface(family, label):
    for seed in (0, 1):
        f = _make(family, seed)
        placed = PlacedFurniture("piece", f, (0.4, -0.3, 0.6 + seed))
        top = placed.contact_surface(label)
        start = top.center + [0.0, 0.0, BALL_RADIUS + 0.15]
        end = _drop_ball(f, placed.pose, start)
        assert end[2] - BALL_RADIUS == pytest.approx(top.center[2], abs=0.015), (family, seed)
        assert np.linalg.norm(end[:2] - top.center[:2]) < 0.02


def test_ball_between_chair_legs_falls_to_the_floor():
    for seed in (0, 1, 2):
        chair = _make("chair", seed)
        placed = PlacedFurniture("piece", chair, (-0.5, 0.2, -1.0))
        seat = chair.contact_surface("seat")
        under = seat.center.copy()
        under[2] = 0.5 * (chair.parts("seat")[0].bounds[0, 2])  # halfway between floor and seat
        # No single hull: below the seat and in front of the backrest is empty space.
        assert not chair.contains(under) and not chair.contains(seat.center + [0.05, 0.0, 0.1])
        end = _drop_ball(chair, placed.pose, placed.to_world(under))
        assert end[2] == pytest.approx(BALL_RADIUS, abs=0.005)


def test_geom_names_and_kinds_in_the_model():
    spec = load_humanoid_spec()
    handles = {}
    for k, family in enumerate(FAMILIES):
        f = _make(family, k)
        handles[family] = add_furniture_to_spec(spec, f, (3.0 + 2.5 * (k % 4), -4.0 + 3.0 * (k // 4), 0.3 * k),
                                                f"{family}_0")
    model = spec.compile()
    for family, handle in handles.items():
        handle.bind(model)
        f = handle.furniture
        counts = Counter()
        for part in f.parts():
            geom = model.geom(f"{family}_0/{part.label}/{counts[part.label]}")
            counts[part.label] += 1
            expected = mujoco.mjtGeom.mjGEOM_BOX if part.is_box else mujoco.mjtGeom.mjGEOM_MESH
            assert geom.type[0] == expected
            assert model.geom_bodyid[geom.id] == handle.body_id
        assert model.body_jntnum[handle.body_id] == 0  # static


# --- rooms and houses ------------------------------------------------------------------------------
def _independent_reachability(room: Room) -> bool:
    """A separate check of the connectivity rule: grid flood fill from the first door."""
    c, radius, reach = 0.05, room.body_radius, room.reach_distance
    x0, y0, x1, y1 = room.bounds
    xs = np.arange(x0 + c / 2, x1, c)
    ys = np.arange(y0 + c / 2, y1, c)
    gx, gy = np.meshgrid(xs, ys)
    centres = np.stack((gx, gy), axis=-1)
    masks = [f.footprint_box().contains_xy(centres) for f in room.furniture]
    blocked = np.pad(np.any(masks, axis=0) if masks else np.zeros(gx.shape, bool), 1, constant_values=True)
    clear = ndimage.distance_transform_edt(~blocked)[1:-1, 1:-1] * c - c / 2 >= radius
    labels, _ = ndimage.label(clear)
    door = room.doors[0]
    p = door.approach_point(room.bounds, room.wall_thickness / 2 + radius + 2 * c)
    start = labels[int((p[1] - y0) // c), int((p[0] - x0) // c)]
    if start == 0:
        return False
    region = labels == start
    for mask in masks:
        near = ndimage.distance_transform_edt(~mask) * c <= reach + c
        if not np.any(region & near):
            return False
    return True


def _check_room(room: Room, clearance: float) -> None:
    x0, y0, x1, y1 = room.bounds
    items = list(room.furniture)
    assert len({f.name for f in items}) == len(items)
    for f in items:
        corners = f.footprint_box().corners_xy()
        assert np.all(corners[:, 0] >= x0 - 1e-6) and np.all(corners[:, 0] <= x1 + 1e-6)
        assert np.all(corners[:, 1] >= y0 - 1e-6) and np.all(corners[:, 1] <= y1 + 1e-6)
        assert not any(f.footprint_box(-1e-6).footprint_overlaps(w) for w in room.walls)
    for i, a in enumerate(items):
        for b in items[i + 1:]:
            gap = footprint_distance(a.footprint_box(), b.footprint_box())
            seat_at_table = {a.family, b.family} & {"chair", "stool"} and "table" in (a.family, b.family)
            assert gap > 1e-6 if seat_at_table else gap >= clearance - 1e-6, (a.name, b.name, gap)
    for door in room.doors:  # the door opening is not walled up
        assert not any(w.contains_xy(np.asarray(door.center)) for w in room.walls)


def test_generated_rooms_are_valid_and_connected():
    config = RoomConfig()
    for seed in range(6):
        room = generate_room(config, np.random.default_rng(seed))
        assert room.furniture and room.room_type in config.room_types
        _check_room(room, config.clearance)
        assert room.is_connected()
        assert _independent_reachability(room)
        wall_backed = [f for f in room.furniture if f.family in ("bed", "double_bed", "wardrobe", "bookshelf", "sofa")]
        for f in wall_backed:  # back to a wall: the back edge lies at the interior's boundary
            back = f.to_world(np.array([-f.furniture.footprint[0], 0.0, 0.0]))
            gaps = [back[0] - room.bounds[0], room.bounds[2] - back[0], back[1] - room.bounds[1], room.bounds[3] - back[1]]
            assert min(gaps) == pytest.approx(config.wall_gap, abs=1e-6)


def test_generate_room_is_pure():
    a = generate_room(RoomConfig(), np.random.default_rng(11))
    b = generate_room(RoomConfig(), np.random.default_rng(11))
    assert [(f.name, f.pose) for f in a.furniture] == [(f.name, f.pose) for f in b.furniture]
    assert a.bounds == b.bounds


def test_requested_categories_are_honoured():
    requests = [["table", "chair", "chair", "chair", "chair"], ["double_bed", "wardrobe", "lamp", "stool"],
                ["sofa", "armchair", "table", "bookshelf", "cabinet", "lamp"], ["bed"]]
    for seed, cats in enumerate(requests):
        room = generate_room(RoomConfig(), np.random.default_rng(seed), categories=cats)
        assert Counter(room.categories) == Counter(cats)
        assert room.room_type == "custom"
        _check_room(room, RoomConfig().clearance)
        assert room.is_connected()
    with pytest.raises(RuntimeError, match="could not place"):
        generate_room(RoomConfig(size_x=(2.0, 2.0), size_y=(2.0, 2.0), max_attempts=2, placement_tries=5),
                      np.random.default_rng(0), categories=["double_bed", "double_bed"])
    with pytest.raises(ValueError, match="categories must be one of"):
        generate_room(RoomConfig(), np.random.default_rng(0), categories=["spaceship"])


def test_layout_graph_nodes_and_edges():
    room = generate_room(RoomConfig(), np.random.default_rng(3), categories=["table", "chair", "chair", "sofa", "lamp"])
    graph = room.layout_graph(threshold=1.0)
    assert set(graph.nodes) == {f.name for f in room.furniture}
    for f in room.furniture:
        node = graph.nodes[f.name]
        assert node["category"] == f.family
        assert node["position"] == pytest.approx(tuple(f.position))
        assert node["important"] == (f.family != "lamp")
    for i, a in enumerate(room.furniture):  # one room: an edge exactly when the footprints are close
        for b in room.furniture[i + 1:]:
            close = footprint_distance(a.footprint_box(), b.footprint_box()) <= 1.0
            assert graph.has_edge(a.name, b.name) == close
    # A wall between two chairs cuts their edge.
    chair = _make("chair", 0)
    items = (PlacedFurniture("chair_0", chair, (-0.6, 0.0, 0.0)), PlacedFurniture("chair_1", chair, (0.6, 0.0, math.pi)))
    wall = Box((0.0, 0.0), (0.05, 2.0), 0.0, 0.0, 2.5)
    door = Door((-3.05, 0.0), 0.9, 0, ("r", "outside"))
    open_room = Room("r", "custom", (-3.0, -3.0, 3.0, 3.0), (), (door,), items)
    walled = Room("r", "custom", (-3.0, -3.0, 3.0, 3.0), (wall,), (door,), items)
    assert open_room.layout_graph().has_edge("chair_0", "chair_1")
    assert not walled.layout_graph().has_edge("chair_0", "chair_1")


def test_house_joins_rooms_through_passable_doors():
    config = RoomConfig()
    house = generate_house(config, np.random.default_rng(4), 4)
    assert len(house.rooms) == 4
    names = {r.name for r in house.rooms}
    inner = [d for d in house.doors if "outside" not in d.rooms]
    assert len(inner) >= 3 and all(set(d.rooms) <= names for d in inner)
    for i, a in enumerate(house.rooms):  # rooms do not overlap
        _check_room(a, config.clearance)
        for b in house.rooms[i + 1:]:
            ax0, ay0, ax1, ay1 = a.bounds
            bx0, by0, bx1, by1 = b.bounds
            assert ax1 <= bx0 or bx1 <= ax0 or ay1 <= by0 or by1 <= ay0
    assert len({f.name for f in house.furniture}) == len(house.furniture)
    for door in house.doors:
        assert door.width >= 2 * config.body_radius
        assert not any(w.contains_xy(np.asarray(door.center)) for w in house.walls)
    # One free region holds a standing point inside every door of every room.
    space = house.free_space()
    depth = config.wall_thickness / 2 + config.body_radius + 2 * config.cell_size
    labels = {int(space.label_at(d.approach_point(r.bounds, depth)[None])[0])
              for r in house.rooms for d in r.doors}
    assert len(labels) == 1 and 0 not in labels
    assert house.is_connected()
    # The graph spans the house; edges never cross a wall.
    graph = house.layout_graph(threshold=1.5)
    assert graph.number_of_nodes() == len(house.furniture)
    for a, b in graph.edges:
        assert graph.nodes[a]["room"] and graph.nodes[b]["room"]
        p, q = np.asarray(graph.nodes[a]["position"]), np.asarray(graph.nodes[b]["position"])
        assert not any(segment_hits_box(p, q, w) for w in house.walls)
    # Requested contents per room.
    custom = generate_house(config, np.random.default_rng(5), 2, categories=[["bed", "lamp"], ["table", "chair"]])
    assert [Counter(r.categories) for r in custom.rooms] == [Counter(["bed", "lamp"]), Counter(["table", "chair"])]


def test_rooms_compile_with_the_humanoid_and_simulate():
    house = generate_house(RoomConfig(), np.random.default_rng(6), 2)
    spec = load_humanoid_spec()
    handles = add_room_to_spec(spec, house)
    model = spec.compile()
    handles.bind(model)
    assert len(handles.wall_geom_ids) == len(house.walls)
    first = next(iter(handles.furniture.values()))
    gid = int(first.geom_ids[first.furniture.labels[0]][0])
    assert handles.geom_label(model, gid) == (first.name, first.furniture.labels[0])
    data = mujoco.MjData(model)
    room = house.rooms[0]
    stand = room.doors[0].approach_point(room.bounds, 0.6)
    data.qpos[:2] = stand  # the humanoid's root (free joint) on free floor inside a door
    mujoco.mj_forward(model, data)
    for _ in range(20):
        mujoco.mj_step(model, data)
    assert np.all(np.isfinite(data.qpos))
    furniture_geoms = set(np.concatenate([np.concatenate(list(h.geom_ids.values())) for h in handles.furniture.values()]))
    humanoid_bodies = set(range(1, model.nbody)) - {h.body_id for h in handles.furniture.values()}
    for k in range(data.ncon):  # standing on free floor: the character touches no furniture
        con = data.contact[k]
        if model.geom_bodyid[con.geom1] in humanoid_bodies or model.geom_bodyid[con.geom2] in humanoid_bodies:
            assert con.geom1 not in furniture_geoms and con.geom2 not in furniture_geoms
