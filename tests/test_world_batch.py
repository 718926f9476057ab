"""``WorldBatch`` moves every copy as Pymunk moves it: each copy is held to a world in which Pymunk takes every step
and the waypoint controller is written out in plain Python (``PymunkWorld``, the oracle), to 1e-9 m."""

import math

import numpy as np
import pytest

from infonav_gym.geometry import wrap_angle
from infonav_gym.world import CircleObstacle, World, physics, world_batch
from infonav_gym.world.active_scenarios import goal_field
from infonav_gym.world.motion_kernels import executed_controls
from infonav_gym.world.physics import ContactSpace
from infonav_gym.world.scenarios import Route, Scenario, build_scenario
from infonav_gym.world.world_batch import WorldBatch, start_poses

TIME_STEP_S = 0.5
TOLERANCE = 1e-9  # Pymunk's substeps of a free step sum to the free motion up to rounding


class PymunkWorld:
    """The oracle: a scenario's robots in a Pymunk space that takes every step (``ContactSpace``, default World
    arguments), each robot driven toward its waypoints by the controller written out here, or by ``command``."""

    def __init__(self, scenario: Scenario):
        self.reference = WorldBatch(1)  # only for its default arguments
        reference = self.reference
        self.space = ContactSpace(scenario, reference.robot_radius_m, reference.wall_thickness_m, 0.1)
        self.routes = scenario.routes
        self.poses = np.array(start_poses(scenario))
        self.waypoint_indices = [0] * len(self.routes)
        self.commands: list[tuple[float, float]] | None = None

    def command(self, speed_mps: float, turn_rate_rps: float, robot: int = 0) -> None:
        """Drive robot ``robot`` at ``speed_mps`` [m/s] and ``turn_rate_rps`` [rad/s] instead of its waypoints."""
        if self.commands is None:
            self.commands = [(0.0, 0.0)] * len(self.routes)
        self.commands[robot] = (float(speed_mps), float(turn_rate_rps))

    def step(self, dt: float) -> np.ndarray:
        """Every robot's executed ``[speed, turn_rate]`` (R, 2) of a Pymunk step of ``dt``."""
        controls = self.commands or [self._waypoint_control(robot, *pose) for robot, pose in enumerate(self.poses)]
        after = self.space.drive(self.poses, np.array(controls), dt)
        executed = executed_controls(self.poses[None], after[None], dt)[0]
        self.poses = after
        return executed

    def _waypoint_control(self, robot: int, x: float, y: float, heading: float) -> tuple[float, float]:
        waypoints, route, world = self.routes[robot].waypoints, self.routes[robot], self.reference
        for _ in range(len(waypoints) + 1):
            if self.waypoint_indices[robot] >= len(waypoints):
                break
            target_x, target_y = waypoints[self.waypoint_indices[robot]]
            if math.hypot(target_x - x, target_y - y) > world.waypoint_tolerance_m:
                heading_error = wrap_angle(math.atan2(target_y - y, target_x - x) - heading)
                limit = world.max_turn_rate_rps
                turn_rate = max(-limit, min(limit, world.heading_gain * heading_error))
                return route.speed_mps * max(math.cos(heading_error), 0.0), turn_rate
            self.waypoint_indices[robot] += 1
            if route.loop and self.waypoint_indices[robot] >= len(waypoints):
                self.waypoint_indices[robot] = 0
        return 0.0, 0.0


def scenarios(name: str, seed: int, n_copies: int, **parameters) -> list[Scenario]:
    rng = np.random.default_rng(seed)
    return [build_scenario(name, rng, **parameters) for _ in range(n_copies)]


def crashing_scenario(offset: float) -> Scenario:
    """Two robots driving head-on into each other, then robot 0 into a wall: many Pymunk contact steps."""
    routes = (
        Route((offset, 0.0, 0.0), np.array([[20.0, 0.0]]), speed_mps=1.5),
        Route((10.0, 0.3, np.pi), np.array([[offset - 5.0, 0.0]]), speed_mps=1.0),
    )
    walls = (((13.0, -5.0), (13.0, 5.0)), ((-8.0, -5.0), (-8.0, 5.0)))
    return Scenario(name="crash", bounds=(-10.0, -10.0, 15.0, 10.0), routes=routes, walls=walls)


def assert_batch_follows_pymunk(scenario_list: list[Scenario], n_steps: int, steps_of=None) -> None:
    """Step a batch and one ``PymunkWorld`` per scenario side by side; poses and executed controls equal to 1e-9."""
    batch = WorldBatch(len(scenario_list))
    references = [PymunkWorld(scenario) for scenario in scenario_list]
    for copy, scenario in enumerate(scenario_list):
        batch.reset_copy(copy, scenario)
    np.testing.assert_array_equal(batch.poses, [reference.poses for reference in references])
    for step in range(n_steps):
        copies = np.arange(len(references)) if steps_of is None else steps_of(step)
        executed = batch.step(TIME_STEP_S, copies)
        expected = np.reshape([references[copy].step(TIME_STEP_S) for copy in copies.tolist()], executed.shape)
        np.testing.assert_allclose(executed, expected, rtol=0, atol=TOLERANCE)
        np.testing.assert_allclose(batch.poses, [reference.poses for reference in references], rtol=0, atol=TOLERANCE)


@pytest.mark.parametrize(
    "name, parameters",
    [("field", {}), ("corridor", {}), ("team_field", {"n_robots": 4}), ("convoy", {"n_robots": 3})],
)
def test_every_copy_moves_as_pymunk_moves_it_on_the_builtin_scenarios(name, parameters):
    assert_batch_follows_pymunk(scenarios(name, 3, 5, **parameters), n_steps=150)


def test_copies_in_contact_take_pymunk_steps():
    batch_scenarios = [crashing_scenario(offset) for offset in (-6.0, -4.0, -2.0)]
    assert_batch_follows_pymunk(batch_scenarios, n_steps=40)
    world = World()
    world.reset(batch_scenarios[0])
    for _ in range(40):
        world.step(TIME_STEP_S)
    assert world.poses[0, 0] < 13.0  # Pymunk stopped robot 0 at the wall before its waypoint (20, 0)


def lapping_scenario(offset: float) -> Scenario:
    """A robot lapping a square whose edges graze a wall and cross an obstacle: a run of contact steps each lap."""
    square = np.array([[8.0, 0.0], [8.0, 8.0], [0.0, 8.0], [0.0, offset]])
    routes = (Route((0.0, offset, 0.0), square, loop=True, speed_mps=1.2),)
    walls = (((-5.0, -0.6), (12.0, -0.6)),)
    obstacles = (CircleObstacle((4.0, 8.2), 0.5),)
    return Scenario(name="laps", bounds=(-10.0, -10.0, 15.0, 15.0), routes=routes, walls=walls, obstacles=obstacles)


def spy_on_pymunk_steps(monkeypatch) -> list[ContactSpace]:
    """The ``ContactSpace`` of every Pymunk step taken from now on, in order."""
    steps, drive = [], ContactSpace.drive
    monkeypatch.setattr(physics.ContactSpace, "drive", lambda space, *args: steps.append(space) or drive(space, *args))
    return steps


@pytest.mark.parametrize("max_idle_spaces", [0, 64])
def test_runs_of_contact_steps_start_alike_in_a_kept_or_a_rebuilt_space(monkeypatch, max_idle_spaces):
    monkeypatch.setattr(world_batch, "MAX_IDLE_SPACES", max_idle_spaces)  # 0: every idle copy's space is dropped
    layouts = [lapping_scenario(offset) for offset in (0.0, -0.1, 0.1)]
    assert_batch_follows_pymunk(layouts, n_steps=200)
    world, in_contact = World(), []
    world.reset(layouts[0])
    pymunk_steps = spy_on_pymunk_steps(monkeypatch)
    for _ in range(200):
        before = len(pymunk_steps)
        world.step(TIME_STEP_S)
        in_contact.append(len(pymunk_steps) > before)
    runs = sum(1 for k, now in enumerate(in_contact) if now and (k == 0 or not in_contact[k - 1]))
    assert runs >= 3  # several separate runs (about one a lap), each after free steps


def test_stepping_some_copies_leaves_the_others_where_they_are():
    rng = np.random.default_rng(0)
    assert_batch_follows_pymunk(
        scenarios("field", 1, 6), n_steps=60, steps_of=lambda step: np.flatnonzero(rng.random(6) < 0.5)
    )


def test_commanded_copies_move_as_pymunk_moves_them():
    rng = np.random.default_rng(7)
    layouts = [goal_field(rng) for _ in range(4)]
    batch, references = WorldBatch(4), [PymunkWorld(layout) for layout in layouts]
    for copy, layout in enumerate(layouts):
        batch.reset_copy(copy, layout)
    for _ in range(120):
        commands = np.stack([rng.uniform(0.0, 2.0, 4), rng.uniform(-1.0, 1.0, 4)], axis=1)[:, None]
        executed = batch.step(TIME_STEP_S, np.arange(4), commands)
        for copy, reference in enumerate(references):
            reference.command(*commands[copy, 0])
            np.testing.assert_allclose(executed[copy], reference.step(TIME_STEP_S), rtol=0, atol=TOLERANCE)
            np.testing.assert_allclose(batch.poses[copy], reference.poses, rtol=0, atol=TOLERANCE)


def test_a_team_driving_side_by_side_moves_as_pymunk_moves_it_through_near_misses_and_bumps(monkeypatch):
    """Four robots 2 m apart in a walled box, driven at random: robots within reach that stay apart take Pymunk's
    contact-free substeps in numpy, the others real contact steps (robots and walls), all as Pymunk moves them."""
    rng = np.random.default_rng(3)
    routes = tuple(Route((7.0 + 2.0 * k, 10.0, rng.uniform(-3, 3)), np.zeros((0, 2))) for k in range(4))
    corners = [(0.0, 0.0), (24.0, 0.0), (24.0, 20.0), (0.0, 20.0)]
    walls = tuple(zip(corners, corners[1:] + corners[:1]))
    layout = Scenario(name="side by side", bounds=(0.0, 0.0, 24.0, 20.0), routes=routes, walls=walls)
    batch, references = WorldBatch(3), [PymunkWorld(layout) for _ in range(3)]
    for copy in range(3):
        batch.reset_copy(copy, layout)
    pymunk_steps, near_misses, free_substeps = spy_on_pymunk_steps(monkeypatch), [], world_batch.free_substeps
    monkeypatch.setattr(
        world_batch, "free_substeps", lambda poses, *args: near_misses.append(len(poses)) or free_substeps(poses, *args)
    )
    for _ in range(300):
        commands = np.stack([rng.uniform(0.0, 1.0, (3, 4)), rng.uniform(-2.0, 2.0, (3, 4))], axis=-1)
        executed = batch.step(1.0, np.arange(3), commands)
        for copy, reference in enumerate(references):
            for robot in range(4):
                reference.command(*commands[copy, robot], robot)
            np.testing.assert_allclose(executed[copy], reference.step(1.0), rtol=0, atol=TOLERANCE)
            np.testing.assert_allclose(batch.poses[copy], reference.poses, rtol=0, atol=TOLERANCE)
    batch_steps = sum(space not in [reference.space for reference in references] for space in pymunk_steps)
    assert sum(near_misses) > 20 and batch_steps > 20  # both kinds, many times


def test_a_copy_with_another_number_of_robots_is_a_clear_error():
    batch = WorldBatch(2)
    batch.reset_copy(0, scenarios("team_field", 0, 1, n_robots=3)[0])
    with pytest.raises(ValueError, match="copy 1: scenario 'team_field' has 4 robots, the other copies 3"):
        batch.reset_copy(1, scenarios("team_field", 0, 1, n_robots=4)[0])


@pytest.mark.parametrize("dt", [0.0, -1.0, 61.0])
def test_a_time_step_outside_its_range_is_a_clear_error(dt):
    batch = WorldBatch(1)
    batch.reset_copy(0, scenarios("field", 0, 1)[0])
    with pytest.raises(ValueError, match="dt"):
        batch.step(dt, np.arange(1))
