"""Pictures of a simulated scene (matplotlib, Agg backend): a PNG or an animated GIF.

The PNG shows the planes, drums, portals (each pair of planes dashed in one colour) and
bodies at the end of the run, each body's
path, the start positions dashed, and the contact normals of the strongest impact
event (the largest total impulse) as arrows coloured by impulse. The GIF shows the
bodies frame by frame with the contact normals of the latest impact.

Circles are drawn as discs, rigidbody2d boxes as rectangles of half-widths ``hx hy``
rotated by their angle theta (corners ``x + R(theta) (+-hx, +-hy)``); a rotating
circle carries a radius line from its centre to ``x + r (cos theta, sin theta)``, so
its spin shows.

A contact normal is drawn at the contact point on body a, pointing along n (the
direction of the impulse on a): ``x_a - r_a n`` for circles, ``x_a + arm_a`` for box
contacts (the arm the contact carries).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.animation import FuncAnimation, PillowWriter  # noqa: E402
from matplotlib.collections import LineCollection, PatchCollection  # noqa: E402
from matplotlib.colors import Normalize  # noqa: E402
from matplotlib.patches import Circle, Polygon  # noqa: E402

from qpbench.atomic import atomic_path
from qpbench.errors import QpbenchError  # noqa: E402
from qpbench.scenes.model import Scene  # noqa: E402
from qpbench.simulation.operators import ChooseSolve  # noqa: E402
from qpbench.simulation.stepper import SimulationResult, Simulator, StepEvent  # noqa: E402

# a progress hook, told (units done, a note or None) after every step simulated and every
# frame drawn (the signature of qpbench.cli.progress.Progress.advance)
Advance = Callable[[int, str | None], None]
MAX_GIF_FRAMES = 80
MAX_PATHS = 300
SUFFIXES = (".png", ".gif")


@dataclass
class Impact:
    """The contacts of one impact event, ready to draw."""

    step: int
    positions: np.ndarray  # (bodies, 2) at the start of the step
    theta: np.ndarray | None  # (bodies,) at the start of the step; None without rotation
    points: np.ndarray  # (n, 2) contact points on ball a
    normals: np.ndarray  # (n, 2)
    impulses: np.ndarray  # (n,)


@dataclass
class Recording:
    """Positions every ``stride`` steps, the latest impact at each frame, the strongest one."""

    stride: int
    radii: np.ndarray
    # the angles after the latest step (the next step's start angles); None: no rotation
    theta: np.ndarray | None = None
    simulator: Simulator | None = None
    frames: list[np.ndarray] = field(default_factory=list)
    frame_thetas: list[np.ndarray | None] = field(default_factory=list)
    frame_steps: list[int] = field(default_factory=list)
    frame_impacts: list[Impact | None] = field(default_factory=list)
    latest: Impact | None = None
    strongest: Impact | None = None

    def __call__(self, event: StepEvent) -> None:
        theta = self.theta  # the event's start-of-step angles
        if self.simulator is not None and self.simulator.theta is not None:
            self.theta = self.simulator.theta.copy()
        if event.contacts.count and event.impulses.size:
            found = event.contacts
            a = found.body_a
            points = event.positions[a] - self.radii[a, None] * found.normals
            if found.arms is not None:
                armed = ~np.isnan(found.arms[:, 0])
                points[armed] = event.positions[a[armed]] + found.arms[armed, :2]
            impact = Impact(event.step, event.positions.copy(), theta, points, found.normals,
                            np.abs(event.impulses[:found.count]))
            self.latest = impact
            if self.strongest is None or impact.impulses.sum() > self.strongest.impulses.sum():
                self.strongest = impact
        if event.step % self.stride == 0:
            self.frames.append(event.positions.copy())
            self.frame_thetas.append(theta)
            self.frame_steps.append(event.step)
            self.frame_impacts.append(self.latest)


def simulate_and_record(scene: Scene, end_time: float | None, steps: int | None,
                        choose_solve: ChooseSolve | None, frames: int,
                        progress: Advance | None = None
                        ) -> tuple[SimulationResult, Recording]:
    """Run the scene, recording about ``frames`` frames; ``progress`` is told after every step.

    Positions are kept every ``total // frames`` steps and after the last, with the latest
    impact at each frame and the strongest impact of the run.

    Parameters
    ----------
    scene : Scene
        The scene to simulate.
    end_time : float or None
        Simulated seconds; None for the scene's ``<end_time>``.
    steps : int or None
        The steps at most; None for no cap.
    choose_solve : ChooseSolve or None
        The inner solve of each operator; None when the scene needs none.
    frames : int
        About how many frames to record.
    progress : Advance or None, optional
        Told ``(1, None)`` after every step; None (default) for no progress.

    Returns
    -------
    tuple of (SimulationResult, Recording)
        The run's summary and what it recorded.

    Raises
    ------
    QpbenchError
        When the scene has no end time and neither ``end_time`` nor ``steps`` is given, or the
        run meets an unsupported contact or runs out of memory.
    """
    simulator = Simulator(scene, choose_solve)
    total = simulator.step_count(end_time, steps)
    recording = Recording(stride=max(1, total // max(frames, 1)), radii=scene.bodies.radii,
                          theta=None if simulator.theta is None else simulator.theta.copy(),
                          simulator=simulator)

    def on_step(event: StepEvent) -> None:
        recording(event)
        if progress is not None:
            progress(1, None)

    result = simulator.run(end_time=end_time, max_steps=steps, on_step=on_step)
    recording.simulator = None
    recording.frames.append(simulator.positions.copy())
    recording.frame_thetas.append(None if simulator.theta is None else simulator.theta.copy())
    recording.frame_steps.append(simulator.step_index)
    recording.frame_impacts.append(recording.latest)
    return result, recording


def _limits(scene: Scene, recording: Recording) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper corners of the view: recorded balls, drums and plane anchors, padded."""
    radii = scene.bodies.radii
    corners = [np.zeros((0, 2))]
    for positions in recording.frames:
        corners += [positions - radii[:, None], positions + radii[:, None]]
    corners += [scene.drum_centers - scene.drum_radii[:, None],
                scene.drum_centers + scene.drum_radii[:, None], scene.plane_points,
                *[np.stack([portal.point_a, portal.point_b]) for portal in scene.portals]]
    points = np.concatenate(corners)
    if points.shape[0] == 0:
        points = np.concatenate([scene.plane_points, np.zeros((1, 2))])
    points = points[np.all(np.isfinite(points), axis=1)]
    lower, upper = points.min(axis=0), points.max(axis=0)
    centre, half = 0.5 * (lower + upper), 0.5 * float(np.max(upper - lower)) * 1.15 + 1e-3
    return centre - half, centre + half


def _draw_boundaries(axes: plt.Axes, scene: Scene, lower: np.ndarray, upper: np.ndarray) -> None:
    span = float(np.max(upper - lower)) * 4.0
    for point, normal in zip(scene.plane_points, scene.plane_normals, strict=True):
        tangent = np.array([-normal[1], normal[0]])
        ends = np.stack([point - span * tangent, point + span * tangent])
        axes.plot(ends[:, 0], ends[:, 1], color="0.2", linewidth=1.5)
        shade = np.stack([ends[0], ends[1], ends[1] - 0.03 * span * normal,
                          ends[0] - 0.03 * span * normal])
        axes.fill(shade[:, 0], shade[:, 1], color="0.85", zorder=0)
    for center, radius in zip(scene.drum_centers, scene.drum_radii, strict=True):
        axes.add_patch(Circle(tuple(center), radius, fill=False, color="0.2", linewidth=1.5))
    for index, portal in enumerate(scene.portals):
        colour = PORTAL_COLOURS[index % len(PORTAL_COLOURS)]
        for point, normal in ((portal.point_a, portal.normal_a),
                              (portal.point_b, portal.normal_b)):
            tangent = np.array([-normal[1], normal[0]])
            ends = np.stack([point - span * tangent, point + span * tangent])
            axes.plot(ends[:, 0], ends[:, 1], color=colour, linewidth=1.5, linestyle="--",
                      label="Lees-Edwards portal" if portal.v else "portal")


PORTAL_COLOURS = ("tab:purple", "tab:green", "tab:brown")  # the two planes of a portal share one


def box_corners(position: np.ndarray, theta: float, half: np.ndarray) -> np.ndarray:
    """(4, 2) corners of a box of half-widths ``half`` at ``position`` rotated by ``theta``.

    Parameters
    ----------
    position : np.ndarray
        (2,) the box's centre.
    theta : float
        Its angle in radians.
    half : np.ndarray
        (2,) its half-widths.

    Returns
    -------
    np.ndarray
        (4, 2) corners, counter-clockwise from ``(-hx, -hy)``.
    """
    c, s = np.cos(theta), np.sin(theta)
    rotation = np.array([[c, -s], [s, c]])
    local = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]]) * half
    return position + local @ rotation.T


def _draw_balls(axes: plt.Axes, scene: Scene, positions: np.ndarray,
                theta: np.ndarray | None = None, **style: object) -> PatchCollection:
    """Every body as a patch: a disc for a circle, a rotated rectangle for a box; with a
    radius line at angle theta on rotating circles (a second collection, same colour)."""
    bodies = scene.bodies
    is_box = bodies.is_box
    angles = np.zeros(bodies.count) if theta is None else theta
    patches = []
    for k, (x, r) in enumerate(zip(positions, bodies.radii, strict=True)):
        if is_box[k]:
            assert bodies.half_widths is not None
            patches.append(Polygon(box_corners(x, float(angles[k]), bodies.half_widths[k]),
                                   closed=True))
        else:
            patches.append(Circle(tuple(x), r))
    collection = PatchCollection(patches, **style)
    axes.add_collection(collection)
    if theta is not None and np.any(~is_box):
        circles = np.flatnonzero(~is_box)
        ends = positions[circles] + bodies.radii[circles, None] * np.stack(
            [np.cos(angles[circles]), np.sin(angles[circles])], axis=1)
        segments = np.stack([positions[circles], ends], axis=1)
        edge = style.get("edgecolor", "tab:blue")
        lines = LineCollection(segments, colors=edge if edge != "none" else "tab:blue",
                               linewidths=1.5, linestyles=style.get("linestyle", "solid"))
        axes.add_collection(lines)
        collection._qpbench_radius_lines = lines  # type: ignore[attr-defined]
    return collection


def _remove_balls(collection: PatchCollection) -> None:
    lines = getattr(collection, "_qpbench_radius_lines", None)
    if lines is not None:
        lines.remove()
    collection.remove()


def _draw_impact(axes: plt.Axes, scene: Scene, impact: Impact | None, norm: Normalize):
    if impact is None or impact.points.shape[0] == 0:
        return None
    length = 1.2 * float(np.median(scene.bodies.radii))
    return axes.quiver(impact.points[:, 0], impact.points[:, 1], impact.normals[:, 0],
                       impact.normals[:, 1], impact.impulses, cmap="plasma", norm=norm,
                       angles="xy", scale_units="xy", scale=1.0 / length, width=0.006,
                       zorder=5)


def _frame_axes(scene: Scene, recording: Recording, panels: int = 1
                ) -> tuple[plt.Figure, list[plt.Axes], Normalize]:
    lower, upper = _limits(scene, recording)
    figure, grid = plt.subplots(1, panels, figsize=(6.4 * panels, 6.4), dpi=100, squeeze=False)
    axes_list = list(grid[0])
    for axes in axes_list:
        axes.set_xlim(lower[0], upper[0])
        axes.set_ylim(lower[1], upper[1])
        axes.set_aspect("equal")
        _draw_boundaries(axes, scene, lower, upper)
    impulses = [impact.impulses for impact in recording.frame_impacts if impact is not None]
    if recording.strongest is not None:
        impulses.append(recording.strongest.impulses)
    top = max((float(np.max(i)) for i in impulses if i.size), default=1.0)
    return figure, axes_list, Normalize(vmin=0.0, vmax=top if top > 0 else 1.0)


def render_png(scene: Scene, recording: Recording, result: SimulationResult, path: Path) -> None:
    """Left: the strongest impact at its step, normals coloured by impulse. Right: the run.

    Without an impact, the run alone: each body's path (up to MAX_PATHS bodies), the start
    positions dashed and the end positions filled.

    Parameters
    ----------
    scene : Scene
        The scene simulated.
    recording : Recording
        What :func:`simulate_and_record` recorded.
    result : SimulationResult
        The run's summary, for the title.
    path : Path
        The PNG file to write, atomically.
    """
    strongest = recording.strongest
    figure, panels, norm = _frame_axes(scene, recording, 2 if strongest is not None else 1)
    run_axes = panels[-1]
    if scene.bodies.count <= MAX_PATHS and len(recording.frames) > 1:
        paths = np.stack(recording.frames)  # (frames, bodies, 2)
        for body in range(scene.bodies.count):
            run_axes.plot(paths[:, body, 0], paths[:, body, 1], color="tab:blue", alpha=0.35,
                          linewidth=0.8)
    _draw_balls(run_axes, scene, recording.frames[0], recording.frame_thetas[0],
                facecolor="none", edgecolor="0.5", linestyle="--", linewidth=0.8)
    _draw_balls(run_axes, scene, recording.frames[-1], recording.frame_thetas[-1],
                facecolor="tab:blue", alpha=0.45, edgecolor="tab:blue")
    run_axes.set_title(f"{scene.name}: {result.steps} steps, {result.impacts} impact steps, "
                       f"t = {result.time:.4g} s\n(dashed: start; filled: end)", fontsize=10)
    if strongest is not None:
        impact_axes = panels[0]
        _draw_balls(impact_axes, scene, strongest.positions, strongest.theta,
                    facecolor="tab:blue", alpha=0.35, edgecolor="tab:blue")
        arrows = _draw_impact(impact_axes, scene, strongest, norm)
        figure.colorbar(arrows, ax=impact_axes, shrink=0.8, label="impulse")
        impact_axes.set_title(f"strongest impact: step {strongest.step}, t = "
                              f"{strongest.step * float(scene.dt):.4g} s, "
                              f"{strongest.points.shape[0]} contacts", fontsize=10)
    figure.tight_layout()
    _save(figure, path, lambda target: figure.savefig(target, format="png"))


def render_gif(scene: Scene, recording: Recording, result: SimulationResult, path: Path,
               progress: Advance | None = None) -> None:
    """The run as an animated gif, one frame per recorded frame.

    Parameters
    ----------
    scene : Scene
        The scene simulated.
    recording : Recording
        What :func:`simulate_and_record` recorded.
    result : SimulationResult
        The run's summary.
    path : Path
        The GIF file to write, atomically.
    progress : Advance or None, optional
        Told after every frame drawn; None (default) for no progress.
    """
    figure, (axes,), norm = _frame_axes(scene, recording)
    balls = _draw_balls(axes, scene, recording.frames[0], recording.frame_thetas[0],
                        facecolor="tab:blue", alpha=0.6, edgecolor="tab:blue")
    title = axes.set_title("", fontsize=10)
    arrows: list[object] = []

    def draw(frame: int) -> list[object]:
        nonlocal balls
        _remove_balls(balls)
        balls = _draw_balls(axes, scene, recording.frames[frame], recording.frame_thetas[frame],
                            facecolor="tab:blue", alpha=0.6, edgecolor="tab:blue")
        while arrows:
            arrows.pop().remove()
        quiver = _draw_impact(axes, scene, recording.frame_impacts[frame], norm)
        if quiver is not None:
            arrows.append(quiver)
        title.set_text(f"{scene.name}: step {recording.frame_steps[frame]}, "
                       f"t = {recording.frame_steps[frame] * float(scene.dt):.4g} s")
        return [balls, title, *arrows]

    animation = FuncAnimation(figure, draw, frames=len(recording.frames), blit=False)

    def frame_written(done: int, total: int) -> None:
        if progress is not None:
            progress(1, f"frame {done + 1} of {total}")

    _save(figure, path, lambda target: animation.save(target, writer=PillowWriter(fps=10),
                                                      progress_callback=frame_written))


def _save(figure: plt.Figure, path: Path, write) -> None:
    """Writes through a temporary file in the same folder, then renames (no half files)."""
    try:
        with atomic_path(path) as temporary:
            write(str(temporary))
    finally:
        plt.close(figure)


def render(scene: Scene, output: str | os.PathLike[str], end_time: float | None = None,
           steps: int | None = None, choose_solve: ChooseSolve | None = None,
           frames: int = MAX_GIF_FRAMES, progress: Advance | None = None
           ) -> SimulationResult:
    """Simulate ``scene`` and draw it to ``output`` (``.png`` or ``.gif``).

    Parameters
    ----------
    scene : Scene
        The scene to simulate.
    output : str or os.PathLike
        The picture to write; its suffix picks the format.
    end_time : float or None, optional
        Simulated seconds; None (default) for the scene's ``<end_time>``.
    steps : int or None, optional
        The steps at most; None (default) for no cap.
    choose_solve : ChooseSolve or None, optional
        The inner solve of each operator; None (default) when the scene needs none.
    frames : int, optional
        Frames of a GIF; MAX_GIF_FRAMES by default (a PNG records 400 for its paths).
    progress : Advance or None, optional
        Told after every step and every frame drawn (:data:`Advance`); None (default) for no
        progress.

    Returns
    -------
    SimulationResult
        The run's summary.

    Raises
    ------
    QpbenchError
        When ``output`` ends in neither ``.png`` nor ``.gif``, or the run cannot go on (see
        :func:`simulate_and_record`).
    """
    path = Path(output)
    if path.suffix.lower() not in SUFFIXES:
        raise QpbenchError(f"{path}: the output must end in .png or .gif")
    result, recording = simulate_and_record(scene, end_time, steps, choose_solve,
                                            frames if path.suffix.lower() == ".gif" else 400,
                                            progress)
    if path.suffix.lower() == ".png":
        render_png(scene, recording, result, path)
        if progress is not None:
            progress(1, f"drew {path.name}")
    else:
        render_gif(scene, recording, result, path, progress)
    return result
