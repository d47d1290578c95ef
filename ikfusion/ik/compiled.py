"""Kinematics and task residuals of one Gauss-Newton step as a single CasADi function.

Building the QP from many small NumPy operations costs milliseconds per step in Python; here
the forward kinematics of the Pinocchio model and every residual with its Jacobian are written
once as a CasADi ``SX`` graph and evaluated in one call (CasADi's virtual machine), so a step
costs about a tenth of a millisecond. The graph follows the Pinocchio model exactly (same joint
placements and joint types); the tests compare it with Pinocchio's own kinematics.

Tangent steps follow Pinocchio: a free-flyer moves by ``M exp(v)`` in its local frame, a
spherical joint by ``R exp(w)``, a revolute joint by adding to its angle. Only first derivatives
at ``dq = 0`` are needed, so the graph uses the first-order forms ``R (I + [w]x)``, which have the
same value and Jacobian there.

Outputs (``k`` tracked segments, ``j`` ball joints, ``m`` sites), all in the world frame:

* ``e_orient`` (3k): ``log(R_world_segment R_world_target^T)`` [rad];
  ``J_orient`` (3k, nv) = ``Jl^-1(e) J_angular``;
* ``e_posture`` (3j): ``log(R_parent_child)`` [rad]; ``B_posture`` (3j, 3) = ``Jr^-1(e)`` blocks;
* ``angles`` (3j): anatomical angles [rad] in sequence order; ``E_inv`` (3j, 3): their rates
  per unit joint tangent step;
* ``p_sites`` (3m) [m] and ``J_sites`` (3m, nv).

The graph holds the model's *structure* only; joint and frame placements are an input, so bodies
of every size share one function. When a C compiler is on the machine the function is compiled
once to a shared library cached under ``$IKFUSION_CACHE`` (default ``~/.cache/ikfusion``) and
evaluates about ten times faster than CasADi's virtual machine, which is the fallback (and the
choice when ``IKFUSION_NO_COMPILE`` is set).
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
from collections.abc import Sequence
from pathlib import Path

import casadi as ca
import numpy as np
import pinocchio as pin

from ..model.ball_joints import BallJoint

_AXES = {"x": 0, "y": 1, "z": 2}


def _skew(w: ca.SX) -> ca.SX:
    return ca.vertcat(ca.horzcat(0, -w[2], w[1]), ca.horzcat(w[2], 0, -w[0]),
                      ca.horzcat(-w[1], w[0], 0))


def _quat_xyzw_to_matrix(q: ca.SX) -> ca.SX:
    x, y, z, w = q[0], q[1], q[2], q[3]
    n = x * x + y * y + z * z + w * w
    s = 2.0 / n
    return ca.vertcat(
        ca.horzcat(1 - s * (y * y + z * z), s * (x * y - w * z), s * (x * z + w * y)),
        ca.horzcat(s * (x * y + w * z), 1 - s * (x * x + z * z), s * (y * z - w * x)),
        ca.horzcat(s * (x * z - w * y), s * (y * z + w * x), 1 - s * (x * x + y * y)),
    )


def _axis_rotation(axis: np.ndarray, angle: ca.SX) -> ca.SX:
    K = ca.DM(np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]],
                        [-axis[1], axis[0], 0.0]]))
    return ca.DM.eye(3) + ca.sin(angle) * K + (1 - ca.cos(angle)) * (K @ K)


def _vee_skew_part(M: ca.SX) -> ca.SX:
    return 0.5 * ca.vertcat(M[2, 1] - M[1, 2], M[0, 2] - M[2, 0], M[1, 0] - M[0, 1])


def _log(X: ca.SX) -> tuple[ca.SX, ca.SX]:
    """Rotation vector of X and its angle (first-order safe near the identity)."""
    v = _vee_skew_part(X)
    c = 0.5 * (X[0, 0] + X[1, 1] + X[2, 2] - 1.0)
    s = ca.sqrt(ca.sumsqr(v) + 1e-300)
    theta = ca.atan2(s, c)
    k = ca.if_else(s > 1e-7, theta / s, 1.0 + s * s / 6.0)
    return k * v, theta


def _jl_inverse(e: ca.SX, theta: ca.SX) -> ca.SX:
    """Inverse left Jacobian of SO(3) at rotation vector e (angle theta)."""
    K = _skew(e)
    t = ca.if_else(theta > 1e-4, theta, 1.0)
    c = ca.if_else(theta > 1e-4, 1.0 / (t * t) - (1.0 + ca.cos(t)) / (2.0 * t * ca.sin(t)),
                   1.0 / 12.0 + theta * theta / 720.0)
    return ca.DM.eye(3) - 0.5 * K + c * (K @ K)


def _euler(sequence: str, R: ca.SX) -> ca.SX:
    i, j, k = (_AXES[a] for a in sequence.lower())
    parity = 1.0 if (j - i) % 3 == 1 else -1.0
    middle = ca.asin(ca.fmin(ca.fmax(parity * R[i, k], -1.0), 1.0))
    first = ca.atan2(-parity * R[j, k], R[k, k])
    last = ca.atan2(-parity * R[i, j], R[i, i])
    return ca.vertcat(first, middle, last)


class CompiledKinematics:
    """The residuals of one IK step for a fixed set of segments, ball joints and sites.

    Args:
        model: Pinocchio model (free-flyer, spherical and revolute joints).
        segment_frames: Frame ids whose orientations are tracked (targets are inputs).
        ball_joints: Ball joints for the posture prior and the ranges of motion.
        site_frames: Frame ids whose positions are needed (sites, contact points, the root).

    Raises:
        NotImplementedError: For joint types the graph does not cover.
    """

    def __init__(self, model: pin.Model, segment_frames: Sequence[int],
                 ball_joints: Sequence[BallJoint], site_frames: Sequence[int]) -> None:
        self.nv = model.nv
        self.segment_frames = list(segment_frames)
        self.site_frames = list(site_frames)
        q = ca.SX.sym("q", model.nq)
        targets = ca.SX.sym("R_world_target", 9 * len(segment_frames))
        frames = sorted(set(self.segment_frames) | set(self.site_frames))
        geometry = ca.SX.sym("geometry", 12 * (model.njoints - 1 + len(frames)))
        self._geometry_frames = frames
        placements = self._placements(geometry, model.njoints - 1, frames)
        rotations, translations, axes = self._forward(model, q, placements)

        e_orient, J_orient = [], []
        for n, fid in enumerate(segment_frames):
            R, _ = self._frame(model, fid, rotations, translations, placements)
            T = ca.reshape(targets[9 * n:9 * n + 9], 3, 3)
            e, theta = _log(R @ T.T)
            J_angular = self._jacobian(model, fid, axes, translations, None)[3:, :]
            e_orient.append(e)
            J_orient.append(_jl_inverse(e, theta) @ J_angular)

        e_post, B_post, angles, E_inv = [], [], [], []
        for joint in ball_joints:
            iq = joint.idx_q
            R_joint = _quat_xyzw_to_matrix(q[iq:iq + 4])
            e, theta = _log(R_joint)
            e_post.append(e)
            B_post.append(_jl_inverse(-e, theta))
            w = ca.SX.sym("w", 3)
            signs = ca.DM(joint.spec.signs)
            a = _euler(joint.spec.sequence, R_joint @ (ca.DM.eye(3) + _skew(w))) * signs
            angles.append(ca.substitute(a, w, ca.DM.zeros(3)))
            E_inv.append(ca.substitute(ca.jacobian(a, w), w, ca.DM.zeros(3)))

        p_sites, J_sites = [], []
        for fid in site_frames:
            _, p = self._frame(model, fid, rotations, translations, placements)
            p_sites.append(p)
            J_sites.append(self._jacobian(model, fid, axes, translations, p)[:3, :])

        def stack(parts: list[ca.SX], cols: int) -> ca.SX:
            return ca.vertcat(*parts) if parts else ca.SX(0, cols)

        self.function = ca.Function(
            "ik_step_residuals", [q, targets, geometry],
            [stack(e_orient, 1), stack(J_orient, model.nv), stack(e_post, 1), stack(B_post, 3),
             stack(angles, 1), stack(E_inv, 3), stack(p_sites, 1), stack(J_sites, model.nv)],
            ["q", "R_world_target", "geometry"],
            ["e_orient", "J_orient", "e_posture", "B_posture", "angles", "E_inv", "p_sites",
             "J_sites"],
        )

    @staticmethod
    def _placements(geometry: ca.SX, n_joints: int, frames: list[int]) -> dict:
        """Symbolic placements: ("joint", j) and ("frame", f) -> (R (3, 3), p (3,))."""
        out = {}
        keys = [("joint", j) for j in range(1, n_joints + 1)] + [("frame", f) for f in frames]
        for n, key in enumerate(keys):
            g = geometry[12 * n:12 * n + 12]
            out[key] = (ca.reshape(g[:9], 3, 3), g[9:12])
        return out

    def geometry(self, model: pin.Model) -> np.ndarray:
        """The geometry input of ``model`` (joint and frame placements; column-major R, then p).

        Bodies of another size share the compiled structure and only change this vector.
        """
        blocks = []
        placements = [model.jointPlacements[j] for j in range(1, model.njoints)]
        placements += [model.frames[f].placement for f in self._geometry_frames]
        for M in placements:
            blocks.append(np.concatenate([M.rotation.T.reshape(-1), M.translation]))
        return np.concatenate(blocks)

    @staticmethod
    def _forward(model: pin.Model, q: ca.SX, placements: dict) -> tuple[list, list, dict]:
        """World rotation and origin of every joint frame, and each tangent column's motion.

        Returns ``axes``: tangent index -> ("angular", world axis) or ("linear", world axis),
        the world-frame motion of the joint frame per unit step of that coordinate.
        """
        rotations: list = [ca.DM.eye(3)]
        translations: list = [ca.DM.zeros(3)]
        axes: dict[int, tuple[str, ca.SX]] = {}
        for j in range(1, model.njoints):
            joint = model.joints[j]
            iq, iv = model.idx_qs[j], model.idx_vs[j]
            R_M, p_M = placements[("joint", j)]
            parent = model.parents[j]
            R_parent = rotations[parent] @ R_M
            p_parent = translations[parent] + rotations[parent] @ p_M
            kind = joint.shortname()
            if kind == "JointModelFreeFlyer":
                R_local = _quat_xyzw_to_matrix(q[iq + 3:iq + 7])
                p_local = q[iq:iq + 3]
                R_world = R_parent @ R_local
                for k in range(3):
                    axes[iv + k] = ("linear", R_world[:, k])
                    axes[iv + 3 + k] = ("angular", R_world[:, k])
            elif kind == "JointModelSpherical":
                R_local = _quat_xyzw_to_matrix(q[iq:iq + 4])
                p_local = ca.SX.zeros(3)
                R_world = R_parent @ R_local
                for k in range(3):
                    axes[iv + k] = ("angular", R_world[:, k])
            elif kind in ("JointModelRX", "JointModelRY", "JointModelRZ",
                          "JointModelRevoluteUnaligned"):
                axis = (np.eye(3)[int(kind[-1] == "Y") + 2 * int(kind[-1] == "Z")]
                        if kind != "JointModelRevoluteUnaligned"
                        else np.asarray(joint.extract().axis))
                R_local = _axis_rotation(axis, q[iq])
                p_local = ca.SX.zeros(3)
                R_world = R_parent @ R_local
                axes[iv] = ("angular", R_world @ ca.DM(axis))
            else:
                raise NotImplementedError(f"joint type {kind} is not compiled")
            rotations.append(R_world)
            translations.append(p_parent + R_parent @ p_local)
        return rotations, translations, axes

    @staticmethod
    def _jacobian(model: pin.Model, fid: int, axes: dict, translations: list,
                  point: ca.SX | None) -> ca.SX:
        """Geometric Jacobian (6, nv) of a frame in the world frame.

        Linear rows (of ``point``) first, then angular rows; only the columns of the frame's
        supporting joints are filled.
        """
        J = ca.SX(6, model.nv)
        joint = model.frames[fid].parentJoint
        for j in model.supports[joint]:
            if j == 0:
                continue
            origin = translations[j]
            for iv in range(model.idx_vs[j], model.idx_vs[j] + model.nvs[j]):
                kind, axis = axes[iv]
                if kind == "linear":
                    J[0:3, iv] = axis
                else:
                    J[3:6, iv] = axis
                    if point is not None:
                        J[0:3, iv] = ca.cross(axis, point - origin)
        return J

    @staticmethod
    def _frame(model: pin.Model, fid: int, rotations: list, translations: list,
               placements: dict) -> tuple:
        j = model.frames[fid].parentJoint
        R_M, p_M = placements[("frame", fid)]
        return rotations[j] @ R_M, translations[j] + rotations[j] @ p_M

    def _bind(self) -> None:
        """Preallocate NumPy inputs, the nonzeros of each output, and dense output arrays."""
        f = self.function
        self._buffer, self._evaluate = f.buffer()
        self._inputs = [np.zeros(f.nnz_in(i)) for i in range(f.n_in())]
        for i, arr in enumerate(self._inputs):
            self._buffer.set_arg(i, memoryview(arr))  # type: ignore[arg-type,call-arg]
        self._nonzeros, self._dense, self._flat = [], [], []
        for i in range(f.n_out()):
            sp = f.sparsity_out(i)
            nz = np.zeros(sp.nnz())
            self._buffer.set_res(i, memoryview(nz))  # type: ignore[arg-type,call-arg]
            rows, cols = (np.array(v, dtype=int) for v in sp.get_triplet())
            self._nonzeros.append(nz)
            self._dense.append(np.zeros((sp.size1(), sp.size2())))
            self._flat.append(rows * sp.size2() + cols)

    def __call__(self, q: np.ndarray, R_world_target: np.ndarray,
                 geometry: np.ndarray) -> list[np.ndarray]:
        """Evaluate at ``q`` with targets (k, 3, 3).

        Returns:
            The outputs as dense arrays, overwritten by the next call (copy to keep them).
        """
        if not hasattr(self, "_buffer"):
            self._bind()
        self._inputs[0][:] = q
        self._inputs[1][:] = np.swapaxes(R_world_target, 1, 2).reshape(-1)  # column-major
        self._inputs[2][:] = geometry
        self._evaluate()
        for dense, flat, nz in zip(self._dense, self._flat, self._nonzeros):
            dense.put(flat, nz)
        return self._dense


def structure_key(model: pin.Model, segment_frames: Sequence[int],
                  ball_joints: Sequence[BallJoint], site_frames: Sequence[int]) -> str:
    """A string identifying the compiled structure (not the geometry) of a step function."""
    parts = [
        ",".join(model.joints[j].shortname() for j in range(1, model.njoints)),
        ",".join(str(p) for p in model.parents),
        ",".join(str(model.frames[f].parentJoint) for f in (*segment_frames, *site_frames)),
        ",".join(str(f) for f in (*segment_frames, *site_frames)),
        ",".join(f"{j.idx_q}:{j.spec.sequence}:{j.spec.signs.tolist()}" for j in ball_joints),
    ]
    for j in range(1, model.njoints):
        if model.joints[j].shortname() == "JointModelRevoluteUnaligned":
            parts.append(str(np.round(model.joints[j].extract().axis, 12).tolist()))
    return hashlib.sha256("|".join(parts).encode()).hexdigest()[:20]


_BUILT: dict[str, CompiledKinematics] = {}


def compiled_kinematics(model: pin.Model, segment_frames: Sequence[int],
                        ball_joints: Sequence[BallJoint],
                        site_frames: Sequence[int]) -> CompiledKinematics:
    """A (cached) :class:`CompiledKinematics`, natively compiled when a C compiler exists."""
    key = structure_key(model, segment_frames, ball_joints, site_frames)
    built = _BUILT.get(key)
    if built is None:
        built = CompiledKinematics(model, segment_frames, ball_joints, site_frames)
        native = _native(built.function, key)
        if native is not None:
            built.function = native
        _BUILT[key] = built
    return built


def cache_dir() -> Path:
    """Folder of compiled step functions."""
    base = os.environ.get("IKFUSION_CACHE")
    if base:
        return Path(base)
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "ikfusion"


def _native(function: ca.Function, key: str) -> ca.Function | None:
    """The function compiled to a shared library (cached on disk), or None without a compiler."""
    if os.environ.get("IKFUSION_NO_COMPILE"):
        return None
    compiler = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if compiler is None:
        return None
    folder = cache_dir()
    library = folder / f"ik_step_{key}_{ca.CasadiMeta.version()}.so"
    try:
        if not library.exists():
            folder.mkdir(parents=True, exist_ok=True)
            with tempfile.TemporaryDirectory(dir=folder) as tmp:
                source = Path(tmp) / "ik_step.c"
                generator = ca.CodeGenerator(source.name, {"with_header": False})
                generator.add(function)
                generator.generate(f"{tmp}{os.sep}")
                built = Path(tmp) / library.name
                subprocess.run([compiler, "-O1", "-shared", "-fPIC", str(source), "-o",
                                str(built), "-lm"], check=True, capture_output=True,
                               timeout=600)
                os.replace(built, library)
        return ca.external(function.name(), str(library))
    except (OSError, subprocess.SubprocessError, RuntimeError):
        return None
