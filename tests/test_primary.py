"""The primary navigation task: route progress, inspection, collisions, timeout, scoring,
and the footprint clearance."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from matplotlib.path import Path as MplPath

from sim.scenario import load_scenario, parse_scenario
from sim.types import Contact, Pose2D
from tasks.geometry import footprint_clearance, polygon_distances
from tasks.primary import (
    CLEARANCE_BIN_EDGES_M,
    EVENT_KINDS,
    PrimaryEvent,
    PrimarySettings,
    PrimaryTask,
    route_from_points,
)

DT = 0.05  # [s], the 20 Hz control tick
A = (1.0, 1.0, 0.0)  # start pose (x, y, yaw)
B = (10.0, 6.0, math.pi / 2)  # dock pose, facing north under the table
CYL = (6.0, 4.0)  # red cylinder centre
CYL_R = 0.2


def scene(*, dock: bool = True, table: bool = True, inspection: str = "red_cylinder"):
    data: dict = {
        "name": "primary_test",
        "bounds": [[0.0, 0.0], [12.0, 8.0]],
        "start": {"x": A[0], "y": A[1], "yaw_deg": 0.0},
        "walls": [{"name": "south", "from": [0.0, 0.0], "to": [12.0, 0.0]}],
        "cylinders": [{"name": "red_cylinder", "centre": list(CYL), "radius": CYL_R}],
        "boxes": [{"name": "crate", "centre": [3.0, 6.0], "size": [0.8, 0.4]}],
        "inspection_object": inspection,
    }
    if table:
        data["tables"] = [{"name": "table", "centre": [10.0, 6.0], "size": [1.2, 0.9]}]
    if dock:
        data["dock"] = {"x": B[0], "y": B[1], "yaw_deg": 90.0}
        if table:
            data["dock"]["table"] = "table"
    return parse_scenario(data, "primary_test.toml")


SCENE = scene()


# ----------------------------------------------------------------- scripted motion


def line(p: tuple, q: tuple, speed: float = 0.5) -> list[tuple[float, float, float]]:
    """Poses from p (excluded) to q (included), position and yaw interpolated linearly."""
    d = math.hypot(q[0] - p[0], q[1] - p[1])
    dyaw = (q[2] - p[2] + math.pi) % (2 * math.pi) - math.pi
    n = max(1, math.ceil(max(d / (speed * DT), abs(dyaw) / (1.0 * DT))))
    return [
        (p[0] + (q[0] - p[0]) * k / n, p[1] + (q[1] - p[1]) * k / n, p[2] + dyaw * k / n)
        for k in range(1, n + 1)
    ]


def arc(
    phi0_deg: float,
    phi1_deg: float,
    *,
    radius: float = 1.0,
    facing_offset_deg: float = 0.0,
    speed: float = 0.3,
) -> list[tuple[float, float, float]]:
    """Poses on a circle about the cylinder, facing its centre (plus an offset)."""
    phi0, phi1 = math.radians(phi0_deg), math.radians(phi1_deg)
    n = max(1, math.ceil(abs(phi1 - phi0) * radius / (speed * DT)))
    out = []
    for k in range(0, n + 1):
        phi = phi0 + (phi1 - phi0) * k / n
        out.append(
            (
                CYL[0] + radius * math.cos(phi),
                CYL[1] + radius * math.sin(phi),
                phi + math.pi + math.radians(facing_offset_deg),
            )
        )
    return out


def on_circle(phi_deg: float, radius: float = 1.0, offset_deg: float = 0.0) -> tuple:
    return arc(phi_deg, phi_deg, radius=radius, facing_offset_deg=offset_deg)[0]


def still(pose: tuple, seconds: float) -> list[tuple[float, float, float]]:
    return [pose] * round(seconds / DT)


def run(
    task: PrimaryTask,
    poses: Sequence[tuple[float, float, float]],
    *,
    clearance: float | Sequence[float] = 0.5,
    contacts: dict[int, Sequence[Contact]] | None = None,
    start: tuple = A,
) -> tuple[list[PrimaryEvent], list[float]]:
    """Tick ``task`` through ``poses`` (tick k at (k + 1) * DT after the last update, the
    robot at ``start`` before the first); the robot-frame velocity is the backward
    difference. Returns the events and the tick times."""
    events: list[PrimaryEvent] = []
    times = []
    prev = start
    t0 = task.t_start + task.elapsed_s
    for k, p in enumerate(poses):
        t = t0 + (k + 1) * DT
        c, s = math.cos(p[2]), math.sin(p[2])
        dx, dy = (p[0] - prev[0]) / DT, (p[1] - prev[1]) / DT
        omega = ((p[2] - prev[2] + math.pi) % (2 * math.pi) - math.pi) / DT
        v = np.array([c * dx + s * dy, -s * dx + c * dy, omega])
        clr = clearance if isinstance(clearance, float | int) else clearance[k]
        events += task.update(t, Pose2D(*p), v, float(clr), (contacts or {}).get(k, ()))
        times.append(t)
        prev = p
    return events, times


def contact(index: int, t: float = 1.0) -> Contact:
    return Contact(index=index, t_start=t, position=np.zeros(2), obstacle="south")


def inspection_then(phi0: float = -90.0, phi1: float = 30.0) -> list[tuple]:
    """A -> onto the circle at phi0 -> arc to phi1 (facing the cylinder)."""
    path = line(A, on_circle(phi0))
    path += arc(phi0, phi1)[1:]
    return path


def full_course(phi0: float = -90.0, phi1: float = 30.0) -> list[tuple]:
    """A -> the inspection arc -> the dock B -> back to A."""
    path = inspection_then(phi0, phi1)
    approach = (B[0], B[1] - 1.0, B[2])
    path += line(path[-1], approach)
    path += line(approach, B)
    path += still(B, 0.5)
    path += line(B, approach)
    path += line(approach, A)
    return path


def kinds(events: Sequence[PrimaryEvent]) -> list[str]:
    return [e.kind for e in events]


# ------------------------------------------------------------------------ geometry


def brute_distance(point: np.ndarray, polygon: np.ndarray) -> float:
    """Point to filled polygon, one edge at a time; inside from matplotlib."""
    if MplPath(polygon).contains_point(point):
        return 0.0
    best = math.inf
    for i in range(len(polygon)):
        a, b = polygon[i], polygon[(i + 1) % len(polygon)]
        ab, ap = b - a, point - a
        s = min(1.0, max(0.0, float(ap @ ab) / float(ab @ ab)))
        best = min(best, float(np.hypot(*(ap - s * ab))))
    return best


def star_polygon(rng: np.random.Generator, k: int) -> np.ndarray:
    """A random simple (star-shaped, often non-convex) polygon."""
    angles = np.sort(rng.uniform(0, 2 * np.pi, k))
    radii = rng.uniform(0.2, 1.0, k)
    centre = rng.uniform(-1, 1, 2)
    return centre + np.column_stack((radii * np.cos(angles), radii * np.sin(angles)))


def test_polygon_distances_match_brute_force(rng):
    for _ in range(20):
        poly = star_polygon(rng, int(rng.integers(3, 9)))
        if rng.random() < 0.5:
            poly = poly[::-1]  # either orientation
        pts = rng.uniform(-2.5, 2.5, (60, 2))
        got = polygon_distances(pts, poly)
        want = np.array([brute_distance(p, poly) for p in pts])
        np.testing.assert_allclose(got, want, atol=1e-12)
        assert np.any(got == 0.0) or not np.any(want == 0.0)
        assert footprint_clearance(pts, poly) == pytest.approx(want.min(), abs=1e-12)


def test_footprint_clearance_of_the_robot_rectangle(rng):
    footprint = SCENE.robot.footprint()
    hx, hy = SCENE.robot.length / 2, SCENE.robot.width / 2
    pts = rng.uniform(-3, 3, (500, 2))
    # Closed form for an axis-aligned rectangle about the origin.
    want = np.hypot(np.maximum(np.abs(pts[:, 0]) - hx, 0), np.maximum(np.abs(pts[:, 1]) - hy, 0))
    np.testing.assert_allclose(polygon_distances(pts, footprint), want, atol=1e-12)
    assert footprint_clearance(pts, footprint) == pytest.approx(want.min(), abs=1e-12)


def test_footprint_clearance_zero_inside_inf_without_points(rng):
    footprint = SCENE.robot.footprint()
    inside = rng.uniform(-0.2, 0.2, (1, 2))
    outside = np.array([[2.0, 0.0], [0.0, -1.25]])
    assert footprint_clearance(np.vstack((outside, inside)), footprint) == 0.0
    assert footprint_clearance(outside, footprint) == pytest.approx(1.0)
    assert footprint_clearance(np.empty((0, 2)), footprint) == math.inf


def test_footprint_clearance_refuses_bad_input():
    with pytest.raises(ValueError, match="polygon"):
        footprint_clearance(np.zeros((1, 2)), np.zeros((2, 2)))
    with pytest.raises(ValueError, match="points"):
        footprint_clearance(np.array([[np.nan, 0.0]]), SCENE.robot.footprint())


# --------------------------------------------------------------------- whole course


def test_scripted_course_completes_with_events_in_order():
    task = PrimaryTask(SCENE)
    poses = full_course()
    events, times = run(task, poses)
    assert kinds(events) == [
        "inspection_started",
        "inspection_done",
        "leg_reached",
        "dock_reached",
        "leg_reached",
        "task_completed",
    ]
    assert [(e.leg_index, e.goal) for e in events if e.kind == "leg_reached"] == [
        (0, "dock"),
        (1, "start"),
    ]
    assert all(e.kind in EVENT_KINDS for e in events)
    assert [e.t for e in events] == sorted(e.t for e in events)
    # The independent reading of the definitions: B within 0.15 m and 15 deg; then A
    # within 0.3 m.
    dock_k = next(
        k
        for k, p in enumerate(poses)
        if math.hypot(p[0] - B[0], p[1] - B[1]) <= 0.15
        and abs((p[2] - B[2] + math.pi) % (2 * math.pi) - math.pi) <= math.radians(15)
    )
    home_k = next(
        k for k, p in enumerate(poses) if k > dock_k and math.hypot(p[0] - A[0], p[1] - A[1]) <= 0.3
    )
    out = task.outcome()
    assert task.done and task.completed and not task.timed_out
    assert task.next_goal is None and task.leg_index == 2
    assert out.completed and not out.timed_out
    assert out.completion_time_s == pytest.approx(times[home_k])
    assert events[-1].t == pytest.approx(times[home_k])
    assert out.leg_times_s == pytest.approx((times[dock_k], times[home_k] - times[dock_k]))
    assert out.collisions == 0 and out.score == pytest.approx(out.completion_time_s)
    assert out.inspection_done and out.inspection_arc_deg >= 90.0
    assert 0 < out.inspection_time_s < times[dock_k]
    # The path up to the completing tick, from the first update's pose.
    xy = np.array([p[:2] for p in poses[: home_k + 1]])
    assert out.path_length_m == pytest.approx(np.sum(np.hypot(*np.diff(xy, axis=0).T)))
    assert out.clearance_samples == home_k + 1
    # Updates after the end change nothing.
    assert task.update(times[-1] + DT, Pose2D(*A), np.zeros(3), 0.0, [contact(9)]) == []
    assert task.outcome() == out


def test_reaching_a_before_b_does_not_complete():
    task = PrimaryTask(SCENE, settings=PrimarySettings(inspection_required=False))
    wander = line(A, (3.0, 1.0, 0.0)) + line((3.0, 1.0, 0.0), A) + still(A, 2.0)
    events, _ = run(task, wander)
    assert events == []
    assert not task.done and task.leg_index == 0 and task.next_goal == "dock"
    out = task.outcome()
    assert not out.completed and out.legs_reached == 0 and out.leg_times_s == ()


def test_dock_needs_the_heading_within_tolerance():
    wrong = (B[0], B[1], B[2] + math.radians(30))
    task = PrimaryTask(SCENE, settings=PrimarySettings(inspection_required=False))
    events, _ = run(task, line(A, wrong) + still(wrong, 1.0))
    assert "dock_reached" not in kinds(events)
    events, _ = run(task, line(wrong, B), start=wrong)
    assert kinds(events) == ["leg_reached", "dock_reached"]


def test_practice_route_to_a_dock_without_table():
    practice = scene(table=False, inspection="")
    task = PrimaryTask(
        practice, settings=PrimarySettings(route=("dock",), inspection_required=False)
    )
    events, _ = run(task, line(A, B))
    assert kinds(events) == ["leg_reached", "dock_reached", "task_completed"]
    assert task.outcome().completed and not task.outcome().inspection_done


def test_missing_inspection_keeps_the_trial_open_until_done():
    task = PrimaryTask(SCENE)
    approach = (B[0], B[1] - 1.0, B[2])
    no_inspection = line(A, approach) + line(approach, B) + line(B, approach)
    no_inspection += line(approach, A) + still(A, 1.0)
    events, times = run(task, no_inspection)
    assert kinds(events) == ["leg_reached", "dock_reached", "inspection_missing"]
    assert not task.done and task.leg_index == 1
    # Back to the cylinder, inspect it, return to A.
    back = inspection_then()
    back += line(back[-1], A)
    more, _ = run(task, back, start=A)
    assert kinds(more) == [
        "inspection_started",
        "inspection_done",
        "leg_reached",
        "task_completed",
    ]
    out = task.outcome()
    assert out.completed and out.inspection_done
    assert out.completion_time_s > times[-1]


def test_missing_inspection_reported_once_per_arrival():
    task = PrimaryTask(SCENE)
    approach = (B[0], B[1] - 1.0, B[2])
    course = line(A, approach) + line(approach, B) + line(B, approach) + line(approach, A)
    course += still(A, 1.0) + line(A, (2.5, 1.0, 0.0)) + line((2.5, 1.0, 0.0), A)
    events, _ = run(task, course)
    assert kinds(events).count("inspection_missing") == 2


def test_optional_inspection_completes_and_flags():
    task = PrimaryTask(SCENE, settings=PrimarySettings(inspection_required=False))
    approach = (B[0], B[1] - 1.0, B[2])
    events, _ = run(task, line(A, approach) + line(approach, B) + line(B, A))
    assert kinds(events)[-1] == "task_completed"
    out = task.outcome()
    assert out.completed and not out.inspection_required and not out.inspection_done
    assert math.isnan(out.inspection_time_s)


# ----------------------------------------------------------------------- inspection


def inspection_events(poses: Sequence[tuple], **kw) -> tuple[list[str], PrimaryTask]:
    task = PrimaryTask(SCENE, **kw)
    events, _ = run(task, poses, start=poses[0])
    return [k for k in kinds(events) if k.startswith("inspection")], task


@pytest.mark.parametrize("phi0, phi1", [(-90, 30), (30, -90), (170, 270), (200, 60)])
def test_an_arc_in_either_direction_counts(phi0, phi1):
    got, task = inspection_events(arc(phi0, phi1))
    assert got == ["inspection_started", "inspection_done"]
    assert 90.0 <= task.inspection_arc_deg < 91.0
    assert task.inspection_done


def test_no_arc_not_facing_too_far_or_too_near_is_no_inspection():
    cases = {
        "short arc": arc(0, 80),
        "facing away": arc(0, 120, facing_offset_deg=180),
        "facing tangentially": arc(0, 120, facing_offset_deg=90),
        "too far": arc(0, 120, radius=CYL_R + 1.8),
        "too near": arc(0, 120, radius=CYL_R + 0.3),
        "standing": still(on_circle(0), 10.0),
        "forward towards it": line(on_circle(0, 1.6), on_circle(0, 0.7)),
    }
    for name, poses in cases.items():
        got, task = inspection_events(poses)
        assert "inspection_done" not in got, name
        assert not task.inspection_done, name
    # The same arc facing it at a distance inside the band does count.
    got, _ = inspection_events(arc(0, 120, radius=CYL_R + 1.5, facing_offset_deg=20))
    assert "inspection_done" in got


def test_forward_motion_around_the_object_does_not_count():
    """Driving around the object with the heading along the motion: not sideways."""
    got, _ = inspection_events(arc(0, 180, facing_offset_deg=90))
    assert got == []


def test_back_and_forth_cancels_and_pause_in_the_band_keeps_the_arc():
    got, task = inspection_events(arc(0, 60) + arc(60, 0)[1:] + arc(0, 60)[1:])
    assert "inspection_done" not in got
    assert task.inspection_arc_deg == pytest.approx(60.0, abs=1.0)
    paused = arc(0, 50) + still(on_circle(50), 3.0) + arc(50, 100)[1:]
    got, _ = inspection_events(paused)
    assert got == ["inspection_started", "inspection_done"]


def test_leaving_the_band_starts_a_new_visit():
    out_and_back = line(on_circle(50), on_circle(50, 3.0)) + line(on_circle(50, 3.0), on_circle(50))
    got, task = inspection_events(arc(0, 50) + out_and_back + arc(50, 100)[1:])
    assert got == ["inspection_started", "inspection_started"]
    assert not task.inspection_done
    assert task.inspection_arc_deg == pytest.approx(50.0, abs=1.0)


def test_a_box_can_be_the_inspection_object():
    crate = scene(inspection="crate")
    task = PrimaryTask(crate)
    cx, cy = 3.0, 6.0
    poses = []
    # Sideways along the crate's long south face and around its east end, facing its centre.
    for k in range(200):
        phi = math.radians(-150 + 120 * k / 199)
        x, y = cx + 1.1 * math.cos(phi), cy + 0.8 * math.sin(phi)
        poses.append((x, y, math.atan2(cy - y, cx - x)))
    events, _ = run(task, poses, start=poses[0])
    assert "inspection_done" in kinds(events)


# ---------------------------------------------------------------------- collisions


def test_collisions_count_once_per_episode_and_add_the_penalty():
    task = PrimaryTask(SCENE)
    poses = full_course()
    first, second = contact(0, 1.0), contact(1, 5.0)
    contacts = {10: [first], 11: [first], 12: [first], 40: [second, first], 41: [second]}
    run(task, poses, contacts=contacts)
    out = task.outcome()
    assert out.completed and out.collisions == 2
    assert out.score == pytest.approx(out.completion_time_s + 2 * 60.0)
    cheap = PrimaryTask(SCENE, settings=PrimarySettings(collision_penalty_s=15.0))
    run(cheap, poses, contacts=contacts)
    assert cheap.outcome().score == pytest.approx(out.completion_time_s + 2 * 15.0)


# ------------------------------------------------------------------------- timeout


def test_timeout_ends_the_trial_at_the_limit():
    task = PrimaryTask(SCENE, settings=PrimarySettings(timeout_s=5.0))
    events, times = run(task, still(A, 8.0), contacts={3: [contact(0)]})
    assert kinds(events) == ["timeout"]
    assert events[0].t == pytest.approx(5.0)
    out = task.outcome()
    assert task.done and task.timed_out and not task.completed
    assert not out.completed and out.timed_out
    assert out.completion_time_s == 5.0 and out.score == pytest.approx(5.0 + 60.0)
    assert out.clearance_samples == round(5.0 / DT)


def test_timer_starts_at_t_start():
    task = PrimaryTask(SCENE, settings=PrimarySettings(timeout_s=5.0), t_start=2.0)
    events, _ = run(task, still(A, 8.0))
    assert events[0].kind == "timeout" and events[0].t == pytest.approx(7.0)


# ------------------------------------------------------------- path and clearance


def test_path_length_of_a_known_polyline():
    corners = [(0.0, 0.0), (3.0, 0.0), (3.0, 4.0), (0.0, 0.0), (0.0, 0.0), (1.0, 1.0)]
    task = PrimaryTask(SCENE, settings=PrimarySettings(inspection_required=False))
    for k, (x, y) in enumerate(corners):
        task.update(k * 0.1, Pose2D(x, y, 0.3 * k), np.zeros(3), 1.0)
    assert task.outcome().path_length_m == pytest.approx(3 + 4 + 5 + 0 + math.sqrt(2))


def test_clearance_statistics_and_fixed_histogram(rng):
    values = np.concatenate((rng.uniform(0, 2.5, 300), CLEARANCE_BIN_EDGES_M[:-1]))
    rng.shuffle(values)
    ticks = [*values, math.inf, math.nan, 2.0]
    task = PrimaryTask(SCENE, settings=PrimarySettings(inspection_required=False))
    for k, c in enumerate(ticks):
        task.update(k * DT, Pose2D(*A), np.zeros(3), c)
    out = task.outcome()
    finite = np.append(values, 2.0)
    assert out.clearance_mean_m == pytest.approx(finite.mean())
    assert out.clearance_std_m == pytest.approx(finite.std())
    assert out.clearance_min_m == pytest.approx(finite.min())
    assert len(out.clearance_histogram) == len(CLEARANCE_BIN_EDGES_M) == 21
    assert out.clearance_samples == len(ticks) - 1 == sum(out.clearance_histogram)
    for k in range(20):  # [edge_k, edge_k+1), every edge value in the bin it opens
        lo, hi = CLEARANCE_BIN_EDGES_M[k], CLEARANCE_BIN_EDGES_M[k + 1]
        assert out.clearance_histogram[k] == np.count_nonzero((finite >= lo) & (finite < hi))
    assert out.clearance_histogram[20] == np.count_nonzero(finite >= 2.0) + 1  # + inf
    with pytest.raises(ValueError, match="clearance_m"):
        task.update(len(ticks) * DT, Pose2D(*A), np.zeros(3), -0.1)


def test_no_clearance_is_nan_statistics():
    task = PrimaryTask(SCENE)
    task.update(0.05, Pose2D(*A), np.zeros(3), math.nan)
    out = task.outcome()
    assert math.isnan(out.clearance_mean_m) and math.isnan(out.clearance_min_m)
    assert out.clearance_samples == 0 and sum(out.clearance_histogram) == 0


# ------------------------------------------------------------------ random sequences


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(1, 300),
    required=st.booleans(),
    route=st.sampled_from([("dock", "start"), ("dock",), ("dock", "start", "dock")]),
)
def test_random_pose_sequences_score_and_leg_order(seed, n, required, route):
    rng = np.random.default_rng(seed)
    s = PrimarySettings(route=route, inspection_required=required, timeout_s=10.0)
    task = PrimaryTask(SCENE, settings=s)
    # Jumps between A, B, the cylinder's surroundings and random points.
    anchors = np.array([[A[0], A[1]], [B[0], B[1]], [CYL[0] + 1.0, CYL[1]], [6.0, 4.0]])
    events: list[PrimaryEvent] = []
    t = 0.0
    for _ in range(n):
        t += float(rng.choice([DT, 0.0, 0.5]))
        xy = (
            anchors[rng.integers(4)] + rng.normal(0, 0.2, 2)
            if rng.random() < 0.7
            else (rng.uniform((0, 0), (12, 8)))
        )
        yaw = B[2] + rng.normal(0, 0.3) if rng.random() < 0.5 else rng.uniform(-np.pi, np.pi)
        contacts = [contact(int(i)) for i in rng.integers(0, 5, rng.integers(0, 3))]
        events += task.update(
            t,
            Pose2D(float(xy[0]), float(xy[1]), float(yaw)),
            rng.normal(0, 0.5, 3),
            float(rng.exponential(0.5)),
            contacts,
        )
    out = task.outcome()
    assert out.score >= 0.0 and out.completion_time_s >= 0.0
    assert out.score == pytest.approx(out.completion_time_s + 60.0 * out.collisions)
    legs = [e for e in events if e.kind == "leg_reached"]
    assert [e.leg_index for e in legs] == list(range(len(legs)))
    assert [e.goal for e in legs] == list(route[: len(legs)])
    assert [e.t for e in events] == sorted(e.t for e in events)
    assert all(x >= 0 for x in out.leg_times_s) and len(out.leg_times_s) == out.legs_reached
    assert kinds(events).count("task_completed") <= 1
    assert kinds(events).count("inspection_done") <= 1
    if out.completed:
        assert kinds(events)[-1] == "task_completed" and out.legs_reached == len(route)
        assert sum(out.leg_times_s) == pytest.approx(out.completion_time_s)
        assert out.inspection_done or not required
    if out.timed_out:
        assert kinds(events)[-1] == "timeout" and out.completion_time_s == 10.0
    assert 0 <= out.collisions <= 5


# ------------------------------------------------------------------ settings, scene


@pytest.mark.parametrize(
    "field, value",
    [
        ("route", ()),
        ("route", ("start",)),
        ("route", ("dock", "dock")),
        ("route", ("dock", "home")),
        ("route", ["dock", "start"]),
        ("inspection_distance_m", (1.0, 0.5)),
        ("inspection_distance_m", (-0.1, 0.5)),
        ("facing_tolerance_deg", 0.0),
        ("facing_tolerance_deg", 200.0),
        ("min_arc_deg", 0.0),
        ("timeout_s", math.inf),
        ("goal_tolerance_m", -1.0),
        ("collision_penalty_s", -60.0),
        ("min_sideways_speed", math.nan),
        ("inspection_required", "yes"),
    ],
)
def test_bad_settings_name_the_field(field, value):
    with pytest.raises(ValueError, match=rf"PrimarySettings\.{field}"):
        dataclasses.replace(PrimarySettings(), **{field: value})


def test_scene_without_dock_or_object_is_refused_when_needed():
    with pytest.raises(ValueError, match=r"primary_test\.toml: field 'dock'"):
        PrimaryTask(scene(dock=False))
    with pytest.raises(ValueError, match=r"primary_test\.toml: field 'inspection_object'"):
        PrimaryTask(scene(inspection=""))
    PrimaryTask(scene(inspection=""), settings=PrimarySettings(inspection_required=False))


def test_time_must_not_go_back():
    task = PrimaryTask(SCENE)
    task.update(1.0, Pose2D(*A), np.zeros(3), 0.5)
    with pytest.raises(ValueError, match="non-decreasing"):
        task.update(0.5, Pose2D(*A), np.zeros(3), 0.5)


def test_the_study_scene_is_accepted():
    room = load_scenario("cluttered_room")
    task = PrimaryTask(room)
    assert task.next_goal == "dock" and not task.done


def test_protocol_route_points_map_to_goals():
    assert route_from_points(["A", "B", "A"]) == ("dock", "start")
    assert route_from_points(("A", "B")) == ("dock",)
    for bad in ([], ["B", "A"], ["A", "C"]):
        with pytest.raises(ValueError, match="route"):
            route_from_points(bad)


def test_rectangle_clearance_equals_the_polygon_one(rng):
    # the closed form for axis-aligned rectangles (any start vertex, either orientation,
    # off-centre) against the general polygon distance, points inside, on and outside
    for _ in range(30):
        x0, y0 = rng.uniform(-1.0, 0.5, 2)
        x1, y1 = x0 + rng.uniform(0.05, 1.5), y0 + rng.uniform(0.05, 1.5)
        box = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
        box = np.roll(box, int(rng.integers(4)), axis=0)
        if rng.random() < 0.5:
            box = box[::-1]
        pts = rng.uniform(-2.5, 2.5, (int(rng.integers(1, 300)), 2))
        pts[: len(pts) // 10] = rng.uniform((x0, y0), (x1, y1), (len(pts) // 10, 2))
        if rng.random() < 0.3:
            pts[-1] = (x1, rng.uniform(y0, y1))  # on the boundary
        want = float(polygon_distances(pts, box).min())
        assert footprint_clearance(pts, box) == pytest.approx(want, abs=1e-12)
    # a rotated rectangle is no axis-aligned one: the general path, still right
    rot = SCENE.robot.footprint() @ np.array([[0.8, 0.6], [-0.6, 0.8]])
    pts = rng.uniform(-3, 3, (200, 2))
    want = min(brute_distance(p, rot) for p in pts)
    assert footprint_clearance(pts, rot) == pytest.approx(want, abs=1e-12)
