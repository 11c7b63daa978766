"""The twin in a browser: a viser scene with a slider per joint and live MuJoCo physics.

Scene tree (every body's content is given in world coordinates at rest, under a frame that
carries the body's relative pose, see :mod:`drawer_lib.viewer.scene`)::

    /twin/static/gaussians          the static scene's Gaussians
    /twin/static/collision/<k>      its collision hulls (hidden until "collision hulls" is on)
    /twin/<id>                      a frame per part or object, moved by its joint
    /twin/<id>/gaussians            that body's Gaussians (interiors included)
    /twin/<id>/collision/<k>        its hulls
    /axes/<id>                      a joint's axis as an arrow (fixed in the world)
    /dropped/<name>                 balls and cups dropped in simulate mode

Two modes:

* **kinematic** (default): a slider per articulated part sets its joint value q; MuJoCo's forward
  kinematics gives the poses. "open all" / "close all" set every slider to its range's end.
* **simulate**: a background thread steps MuJoCo in real time (or slower, if the CPU cannot
  keep up; the panel shows the real-time factor) and streams body poses ~30 times a second. The
  sliders become targets: each joint's velocity servo (the twin's own actuator) is commanded
  ``clip((target - q) / tau, ctrlrange)``, so contacts can stop a part short of its target. "drop
  ball" / "drop cup" add a free body above where the camera looks (MuJoCo's ``mj_ray`` against
  the collision geoms) and recompile the model, keeping the state of everything else.
"""

import math
import threading
import time
from dataclasses import dataclass

import mujoco
import numpy as np
import trimesh
import viser

from drawer_lib.sim.mjcf import BIT_PART, BIT_RIGID, BIT_STATIC, GROUP_COLLISION, set_drives
from drawer_lib.viewer.scene import TwinScene, relative_poses

FPS = 30.0  # pose updates per second sent to the browser
TRACK_TAU = 0.25  # s, time constant of the target-tracking command in simulate mode
COLORS = {"revolute": (255, 150, 40), "prismatic": (40, 190, 230)}
LOW_MARGIN_COLOR = (230, 30, 60)  # the axis of a part whose type decision had a low margin
LOW_MARGIN_MARK = "⚠ "  # before its slider's label
HULL_COLORS = {"static": (0.55, 0.55, 0.62), "part": (0.2, 0.75, 0.35), "rigid": (0.85, 0.35, 0.3)}
CUP_RADIUS, CUP_HEIGHT, CUP_WALL = 0.04, 0.09, 0.005
BALL_RADIUS = 0.03


@dataclass
class Dropped:
    """A body the user dropped: its name (MuJoCo body and scene node), kind and viser frame."""

    name: str
    kind: str
    frame: viser.FrameHandle


def cup_pieces(n: int = 10) -> list[tuple[str, list[float], list[float], float]]:
    """A cup as convex pieces (MuJoCo collides meshes as hulls, so a hollow cup is made of them):
    a bottom disc and ``n`` wall boxes closing a ring; (``cylinder`` | ``box``, MuJoCo size,
    position, yaw in rad) in the cup's frame (origin at the centre of its bottom face, +z up)."""
    pieces = [("cylinder", [CUP_RADIUS, CUP_WALL / 2, 0.0], [0.0, 0.0, CUP_WALL / 2], 0.0)]
    w = 2 * CUP_RADIUS * math.tan(math.pi / n)  # the chord that closes the ring
    r = CUP_RADIUS - CUP_WALL / 2
    for k in range(n):
        a = 2 * math.pi * k / n
        pieces.append(("box", [CUP_WALL / 2, w / 2, CUP_HEIGHT / 2], [r * math.cos(a), r * math.sin(a), CUP_HEIGHT / 2], a))
    return pieces


class TwinViewer:
    """A viser server showing ``scene``; see the module docstring. ``server`` may be shared.

    Thread safety: GUI callbacks run on viser's thread pool and the physics on its own thread;
    every access to the MuJoCo state holds ``self.lock``."""

    def __init__(self, scene: TwinScene, server: viser.ViserServer, show_collision: bool = False,
                 show_axes: bool = True):
        self.scene, self.server = scene, server
        self.lock = threading.RLock()
        self.model = self._own(scene.model)
        self.data = mujoco.MjData(self.model)
        mujoco.mj_kinematics(self.model, self.data)
        self.spec: mujoco.MjSpec | None = None  # loaded on the first drop
        self.dropped: list[Dropped] = []
        self.targets = {b.id: 0.0 for b in scene.bodies if b.articulated}
        self._sim_thread: threading.Thread | None = None
        self._stop = threading.Event()
        self.rt_factor = float("nan")
        self.frames: dict[str, viser.FrameHandle] = {}
        self.hulls: list = []
        self.axes: list = []
        self.splats: list = []
        t0 = time.perf_counter()
        self._build_scene(show_collision, show_axes)
        self._build_gui(show_collision, show_axes)
        self.build_s = time.perf_counter() - t0

    # ------------------------------------------------------------------ scene
    def _hull_nodes(self, prefix: str, hulls, color, visible: bool) -> None:
        for k, (v, f) in enumerate(hulls):
            self.hulls.append(self.server.scene.add_mesh_simple(
                f"{prefix}/collision/{k}", v.astype(np.float32), f.astype(np.uint32), color=color, opacity=0.45,
                flat_shading=True, visible=visible, cast_shadow=False, receive_shadow=False))

    def _splat_node(self, name: str, s) -> None:
        if s is not None and len(s):
            self.splats.append(self.server.scene.add_gaussian_splats(
                name, centers=s.centers, covariances=s.covariances, rgbs=s.rgbs, opacities=s.opacities))

    def _build_scene(self, show_collision: bool, show_axes: bool) -> None:
        sc, scene = self.scene, self.server.scene
        scene.set_up_direction("+z")
        scene.add_frame("/twin", show_axes=False)
        scene.add_frame("/twin/static", show_axes=False)
        self._splat_node("/twin/static/gaussians", sc.static.splats)
        self._hull_nodes("/twin/static", sc.static.hulls, HULL_COLORS["static"], show_collision)
        for b in sc.bodies:
            self.frames[b.id] = scene.add_frame(f"/twin/{b.id}", show_axes=False)
            self._splat_node(f"/twin/{b.id}/gaussians", b.splats)
            self._hull_nodes(f"/twin/{b.id}", b.hulls, HULL_COLORS["rigid" if b.kind == "rigid" else "part"], show_collision)
            if b.joint is not None:
                j = b.joint
                length = 0.3 if j.kind == "revolute" else max(0.15, j.range[1])
                self.axes.append(scene.add_arrows(
                    f"/axes/{b.id}", np.array([[j.anchor, j.anchor + length * j.axis]], np.float32),
                    LOW_MARGIN_COLOR if b.low_margin else COLORS[j.kind],
                    shaft_radius=0.008, head_radius=0.02, head_length=0.05, visible=show_axes))
        self._set_initial_camera()

    def _set_initial_camera(self) -> None:
        """Look at the articulated parts from in front of them: the mean opening direction of the
        drawers (else the direction from the scene's centre to the parts), far enough to frame
        their joints (at least 1.5 m), raised by a third of that distance."""
        lo, hi = self.scene.bounds()
        centre = (lo + hi) / 2
        parts = [b for b in self.scene.bodies if b.joint is not None]
        if parts:
            look = np.mean([b.joint.anchor for b in parts], 0)
            slides = [b.joint.axis for b in parts if b.kind == "prismatic"]
            out = np.mean(slides, 0) if slides else look - centre
            extent = float(np.ptp(np.array([b.joint.anchor for b in parts]), 0).max())
        else:
            look, out, extent = centre, np.array([0.0, -1.0, 0.0]), float((hi - lo).max())
        out = out * np.array([1.0, 1.0, 0.0])
        out = out / np.linalg.norm(out) if np.linalg.norm(out) > 1e-6 else np.array([0.0, -1.0, 0.0])
        dist = max(1.5, 0.6 * extent / math.tan(math.radians(30)))
        self.server.initial_camera.look_at = tuple(look)
        self.server.initial_camera.position = tuple(look + dist * out + np.array([0.0, 0.0, dist / 3]))
        self.server.initial_camera.up = (0.0, 0.0, 1.0)

    # -------------------------------------------------------------------- GUI
    def _build_gui(self, show_collision: bool, show_axes: bool) -> None:
        gui = self.server.gui
        sc = self.scene
        gui.configure_theme(control_width="medium", show_share_button=False)
        self.info = gui.add_markdown(self._info_text())
        self.sliders: dict[str, viser.GuiInputHandle] = {}
        with gui.add_folder("Joints"):
            for b in sc.bodies:
                if b.joint is None:
                    continue
                lo, hi = b.joint.range
                unit = "rad" if b.kind == "revolute" else "m"
                hint = f"{b.kind} joint, {unit}"
                if b.confidence is not None:
                    hint += f"; type decided with confidence {b.confidence:.2f}"
                if b.low_margin:
                    hint += " (low margin: the runner-up kind or hinge side was close)"
                s = gui.add_slider((LOW_MARGIN_MARK if b.low_margin else "") + b.id, min=float(lo), max=float(hi),
                                   step=float((hi - lo) / 200 or 1e-3), initial_value=float(min(max(0.0, lo), hi)),
                                   hint=hint)
                s.on_update(lambda ev, pid=b.id: self._on_slider(pid))
                self.sliders[b.id] = s
            self.open_btn = gui.add_button("open all")
            self.close_btn = gui.add_button("close all")
        self.open_btn.on_click(lambda _: self.open_all())
        self.close_btn.on_click(lambda _: self.close_all())
        with gui.add_folder("Physics"):
            self.sim_box = gui.add_checkbox("simulate (MuJoCo)", initial_value=False,
                                            hint="step the twin in real time; sliders become targets of the joints' drives")
            self.ball_btn = gui.add_button("drop ball", disabled=True, hint="where the camera looks")
            self.cup_btn = gui.add_button("drop cup", disabled=True, hint="where the camera looks")
            self.clear_btn = gui.add_button("remove dropped", disabled=True)
        self.sim_box.on_update(lambda _: self.simulate(self.sim_box.value))
        self.ball_btn.on_click(lambda ev: self.drop("ball", self._client_aim(ev.client)))
        self.cup_btn.on_click(lambda ev: self.drop("cup", self._client_aim(ev.client)))
        self.clear_btn.on_click(lambda _: self.clear_dropped())
        with gui.add_folder("Show"):
            g = gui.add_checkbox("Gaussians", initial_value=True)
            h = gui.add_checkbox("collision hulls", initial_value=show_collision)
            a = gui.add_checkbox("joint axes", initial_value=show_axes)
        g.on_update(lambda _: self._set_visible(self.splats, g.value))
        h.on_update(lambda _: self._set_visible(self.hulls, h.value))
        a.on_update(lambda _: self._set_visible(self.axes, a.value))

    def _info_text(self) -> str:
        sc = self.scene
        n_art = sum(b.articulated for b in sc.bodies)
        rt = "" if math.isnan(self.rt_factor) else f" · physics at **{self.rt_factor:.2f}×** real time"
        name = f"{sc.folder.parent.name}/{sc.folder.name}" if sc.folder.name == "twin" else sc.folder.name
        low = [b.id for b in sc.bodies if b.low_margin]
        warn = f" · {LOW_MARGIN_MARK}low-margin: {', '.join(low)}" if low else ""
        return (f"**{name}** · {sc.n_gaussians:,} Gaussians · {n_art} joints · "
                f"{len(sc.bodies) - n_art} objects{rt}{warn}")

    @staticmethod
    def _set_visible(handles, on: bool) -> None:
        for h in handles:
            h.visible = on

    @staticmethod
    def _own(m: mujoco.MjModel) -> mujoco.MjModel:
        """``m`` with MuJoCo's auto-reset off (a diverged state then shows as non-finite, which
        :meth:`step` reports, instead of a silent jump back to rest) and the parts' drives on
        (the twin loads passive; the sliders command the drives)."""
        m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)
        return set_drives(m, True)

    # ------------------------------------------------------------ kinematics
    def _qadr(self, pid: str) -> int:
        j = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_JOINT, pid)
        return int(self.model.jnt_qposadr[j])

    def q(self, pid: str) -> float:
        """Joint value of part ``pid`` now (rad or m)."""
        with self.lock:
            return float(self.data.qpos[self._qadr(pid)])

    def _on_slider(self, pid: str) -> None:
        v = float(self.sliders[pid].value)
        with self.lock:
            self.targets[pid] = v
            if self.simulating:
                return
            self.data.qpos[self._qadr(pid)] = v
            mujoco.mj_kinematics(self.model, self.data)
            self.push_poses()

    def set_q(self, pid: str, q: float) -> None:
        """Set part ``pid``'s slider to ``q`` (clipped to its range): in kinematic mode the part
        moves there, in simulate mode its drive tracks it."""
        s = self.sliders[pid]
        s.value = float(min(max(q, s.min), s.max))

    def open_all(self) -> None:
        for s in self.sliders.values():
            s.value = s.max

    def close_all(self) -> None:
        for s in self.sliders.values():
            s.value = float(min(max(0.0, s.min), s.max))

    def push_poses(self) -> None:
        """Send every body's relative pose (and the dropped bodies' poses) in one update."""
        sc, d = self.scene, self.data
        ids = [b.mj_body for b in sc.bodies]
        pos, wxyz = relative_poses(d.xpos[ids], d.xquat[ids], sc.rest_xpos[ids], sc.rest_xquat[ids])
        with self.server.atomic():
            for b, p, q in zip(sc.bodies, pos, wxyz):
                f = self.frames[b.id]
                f.position, f.wxyz = p, q
            for o in self.dropped:
                bid = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, o.name)
                o.frame.position, o.frame.wxyz = d.xpos[bid].copy(), d.xquat[bid].copy()

    # ---------------------------------------------------------------- physics
    @property
    def simulating(self) -> bool:
        return self._sim_thread is not None

    def simulate(self, on: bool) -> None:
        """Start or stop the physics thread (idempotent). On stop, the sliders take the joints'
        current values and kinematic mode resumes from there."""
        if on and not self.simulating:
            with self.lock:
                self.data.qvel[:] = 0.0
            self._stop.clear()
            self._sim_thread = threading.Thread(target=self._run, name="twin-physics", daemon=True)
            self._sim_thread.start()
        elif not on and self.simulating:
            self._stop.set()
            self._sim_thread.join(timeout=10)
            self._sim_thread = None
            self.rt_factor = float("nan")
            for pid, s in self.sliders.items():
                s.value = float(min(max(self.q(pid), s.min), s.max))
            self.info.content = self._info_text()
        for b in (self.ball_btn, self.cup_btn, self.clear_btn):
            b.disabled = not on
        if self.sim_box.value != on:
            self.sim_box.value = on

    def _drives(self) -> tuple[list[str], np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(part ids, actuator ids, qpos addresses, ctrl lower, ctrl upper) of the parts that have
        a drive, for the current model (cached per model: a drop recompiles it)."""
        m = self.model
        if getattr(self, "_drives_of", None) is not m:
            ids, acts, qadr = [], [], []
            for pid in self.targets:
                a = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, pid)
                if a >= 0:
                    ids.append(pid)
                    acts.append(a)
                    qadr.append(self._qadr(pid))
            acts = np.array(acts, int)
            limited = m.actuator_ctrllimited[acts].astype(bool)
            lo = np.where(limited, m.actuator_ctrlrange[acts, 0], -np.inf)
            hi = np.where(limited, m.actuator_ctrlrange[acts, 1], np.inf)
            self._drives_cache, self._drives_of = (ids, acts, np.array(qadr, int), lo, hi), m
        return self._drives_cache

    def step(self, seconds: float) -> None:
        """Advance the physics by ``seconds`` of simulated time and send the poses (the thread's
        unit of work; also what tests call, without threads). A state gone non-finite raises
        ``FloatingPointError`` (MuJoCo's silent auto-reset is off, see :meth:`_own`)."""
        with self.lock:
            m, d = self.model, self.data
            ids, acts, qadr, lo, hi = self._drives()
            target = np.array([self.targets[p] for p in ids])
            for _ in range(max(1, round(seconds / m.opt.timestep))):
                if ids:  # each drive tracks its target: clip((target - q) / TRACK_TAU, ctrlrange)
                    d.ctrl[acts] = np.clip((target - d.qpos[qadr]) / TRACK_TAU, lo, hi)
                mujoco.mj_step(m, d)
                if not (np.isfinite(d.qpos).all() and np.isfinite(d.qvel).all()):
                    raise FloatingPointError(f"the simulation diverged at t = {d.time:.3f} s")
            self.push_poses()

    def _run(self) -> None:
        period = 1.0 / FPS
        t_wall, t_sim, last_info = time.perf_counter(), 0.0, 0.0
        while not self._stop.is_set():
            t0 = time.perf_counter()
            try:
                self.step(period)
            except FloatingPointError as e:  # never show NaN poses: back to rest, and say so
                with self.lock:
                    mujoco.mj_resetData(self.model, self.data)
                    mujoco.mj_forward(self.model, self.data)
                    self.push_poses()
                self.info.content = f"**{e}**: every body was reset to rest"
                last_info = time.perf_counter() + 5.0  # keep the message up for a while
                continue
            t_sim += period
            elapsed = time.perf_counter() - t0
            if elapsed < period:
                time.sleep(period - elapsed)
            now = time.perf_counter()
            if now - last_info > 1.0:
                self.rt_factor = t_sim / (now - t_wall)
                self.info.content = self._info_text()
                last_info, t_wall, t_sim = now, now, 0.0

    def _client_aim(self, client: viser.ClientHandle | None) -> np.ndarray:
        if client is None:  # a click that came from Python: above the middle of the scene
            lo, hi = self.scene.bounds()
            return np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, hi[2] + 0.2])
        return self.aim(np.asarray(client.camera.position, float), np.asarray(client.camera.look_at, float))

    def aim(self, eye: np.ndarray, look_at: np.ndarray) -> np.ndarray:
        """Where a dropped body starts for a camera at ``eye`` looking at ``look_at`` (world, m):
        12 cm back along the view ray from the first collision geom it hits (``mj_ray``; 1.5 m
        ahead when it hits nothing), lifted 5 cm."""
        v = np.asarray(look_at, float) - eye
        v = v / np.linalg.norm(v)
        groups = np.zeros(6, np.uint8)
        groups[GROUP_COLLISION] = 1
        geom = np.zeros(1, np.int32)
        with self.lock:
            dist = mujoco.mj_ray(self.model, self.data, np.asarray(eye, float), v, groups, 1, -1, geom)
        hit = eye + (dist - 0.12 if dist >= 0 else 1.5) * v
        return hit + np.array([0.0, 0.0, 0.05])

    def drop(self, kind: str, position) -> str:
        """Add a ball or a cup as a free body at ``position`` (world, m) and go on simulating with
        everything else's state unchanged; returns its name."""
        if kind not in ("ball", "cup"):
            raise ValueError(f"drop: kind {kind!r} (ball or cup)")
        with self.lock:
            if self.spec is None:
                self.spec = mujoco.MjSpec.from_file(str(self.scene.xml))
                # the twin's bodies carry explicit inertials (scene.xml sets inertiafromgeom
                # false); "auto" keeps those and gives the dropped bodies theirs from geom density
                self.spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_AUTO
            name = f"dropped_{kind}_{len(self.dropped)}"
            body = self.spec.worldbody.add_body(name=name, pos=list(map(float, position)))
            body.add_freejoint(name=name)
            bits = dict(contype=BIT_RIGID, conaffinity=BIT_STATIC | BIT_PART | BIT_RIGID, group=GROUP_COLLISION)
            if kind == "ball":
                body.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[BALL_RADIUS, 0, 0], density=300.0, **bits)
            else:
                for t, size, p, yaw in cup_pieces():
                    body.add_geom(type=mujoco.mjtGeom.mjGEOM_CYLINDER if t == "cylinder" else mujoco.mjtGeom.mjGEOM_BOX,
                                  size=size, pos=p, quat=[math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)],
                                  density=800.0, **bits)
            old_m, old_d = self.model, self.data
            m = self._own(self.spec.compile())
            d = mujoco.MjData(m)
            # new bodies are appended: every earlier joint keeps its qpos / dof address
            d.qpos[:old_m.nq] = old_d.qpos
            d.qvel[:old_m.nv] = old_d.qvel
            d.ctrl[:old_m.nu] = old_d.ctrl
            d.time = old_d.time
            mujoco.mj_forward(m, d)
            self.model, self.data = m, d
            frame = self.server.scene.add_frame(f"/dropped/{name}", show_axes=False,
                                                position=tuple(map(float, position)))
            if kind == "ball":
                self.server.scene.add_icosphere(f"/dropped/{name}/mesh", radius=BALL_RADIUS, color=(230, 60, 50))
            else:
                shell = trimesh.creation.annulus(r_min=CUP_RADIUS - CUP_WALL, r_max=CUP_RADIUS, height=CUP_HEIGHT)
                shell.apply_translation([0, 0, CUP_HEIGHT / 2])
                base = trimesh.creation.cylinder(radius=CUP_RADIUS, height=CUP_WALL)
                base.apply_translation([0, 0, CUP_WALL / 2])
                cup = trimesh.util.concatenate([shell, base])
                self.server.scene.add_mesh_simple(f"/dropped/{name}/mesh", np.asarray(cup.vertices, np.float32),
                                                  np.asarray(cup.faces, np.uint32), color=(60, 120, 230))
            self.dropped.append(Dropped(name, kind, frame))
            self.push_poses()
        return name

    def body_position(self, name: str) -> np.ndarray:
        """World position (m) of MuJoCo body ``name`` now."""
        with self.lock:
            return self.data.xpos[mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, name)].copy()

    def clear_dropped(self) -> None:
        """Remove every dropped body (the twin's state is kept)."""
        with self.lock:
            if not self.dropped:
                return
            old_d = self.data
            self.spec = None
            m = self.scene.model
            d = mujoco.MjData(m)
            d.qpos[:] = old_d.qpos[:m.nq]
            d.qvel[:] = old_d.qvel[:m.nv]
            d.ctrl[:] = old_d.ctrl[:m.nu]
            mujoco.mj_forward(m, d)
            self.model, self.data = m, d
            for o in self.dropped:
                o.frame.remove()
            self.dropped = []

    def close(self) -> None:
        """Stop the physics thread (the server is the caller's)."""
        if self.simulating:
            self._stop.set()
            self._sim_thread.join(timeout=10)
            self._sim_thread = None
