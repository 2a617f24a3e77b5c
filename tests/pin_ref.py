"""Reference dynamics: a :class:`kinematics.model.Model` converted to a pinocchio model.

Used by the tests (our algorithms must agree to 1e-9) and by ``bench/bench_rnea.py``.

Each body becomes one pinocchio joint with the body's inertia attached at the joint frame
(our body frame is pinocchio's joint frame). Joints are added in depth-first order, which
pinocchio's algorithms (crba) assume; ``PinRef.jid[i]`` is body i's joint id. A fixed joint
becomes a revolute joint that is always held at q = v = a = 0: it moves nothing, and
pinocchio's ``data.f`` then also holds the wrench that the fixed joint transmits.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from kinematics.model import Model


def depth_first(model: Model) -> list[int]:
    """Body indices in depth-first (pre-)order, children in index order."""
    children: dict[int, list[int]] = {}
    for i, p in enumerate(model.parents):
        children.setdefault(p, []).append(i)
    order: list[int] = []
    stack = list(reversed(children.get(-1, [])))
    while stack:
        i = stack.pop()
        order.append(i)
        stack.extend(reversed(children.get(i, [])))
    return order


class PinRef:
    """A pinocchio model and data mirroring ``model``, with index maps both ways."""

    def __init__(self, model: Model) -> None:
        self.model = model
        pm = pin.Model()
        pm.gravity = pin.Motion(np.asarray(model.gravity, dtype=float), np.zeros(3))
        self.jid = [0] * model.nbodies
        for i in depth_first(model):
            b, j = model.bodies[i], model.joints[i]
            axis = j.axis if j.movable else np.array([0.0, 0.0, 1.0])
            placement = pin.SE3(np.array(j.origin[:3, :3]), np.array(j.origin[:3, 3]))
            parent = 0 if j.parent < 0 else self.jid[j.parent]
            jm = pin.JointModelRevoluteUnaligned(axis)
            self.jid[i] = pm.addJoint(parent, jm, placement, j.name)
            inertia = pin.Inertia(b.mass, np.array(b.com), np.array(b.inertia))
            pm.appendBodyToJoint(self.jid[i], inertia, pin.SE3.Identity())
        self.pin_model = pm
        self.data = pm.createData()
        # index in pinocchio's q of each coordinate of our q
        self.cols = [pm.joints[self.jid[i]].idx_q for i in model.q_joints]

    def expand(self, x: np.ndarray) -> np.ndarray:
        """Our (nv,) joint vector as pinocchio's (nbodies,), zero at fixed joints."""
        out = np.zeros(self.pin_model.nq)
        out[self.cols] = x
        return out

    def fext(self, f: np.ndarray) -> list:
        """Our (nbodies, 6) body-frame wrenches as pinocchio's per-joint Force list."""
        out = [pin.Force.Zero() for _ in range(self.pin_model.njoints)]
        for i, w in enumerate(np.asarray(f, dtype=float)):
            out[self.jid[i]] = pin.Force(w)
        return out

    def rnea(self, q, v, a, fext=None) -> np.ndarray:
        """pinocchio's rnea on one configuration, as our (nv,) torques."""
        args = [self.pin_model, self.data, self.expand(q), self.expand(v), self.expand(a)]
        if fext is not None:
            args.append(self.fext(fext))
        return pin.rnea(*args)[self.cols]

    def wrenches(self) -> np.ndarray:
        """``data.f`` after the last rnea, as our (nbodies, 6)."""
        return np.array([self.data.f[k].vector for k in self.jid])

    def crba(self, q) -> np.ndarray:
        """pinocchio's joint-space inertia matrix (nv, nv), both triangles."""
        M = pin.crba(self.pin_model, self.data, self.expand(q))
        M = np.triu(M) + np.triu(M, 1).T
        return M[np.ix_(self.cols, self.cols)]

    def placements(self, q) -> np.ndarray:
        """World transforms (nbodies, 4, 4) of the bodies (``data.oMi``)."""
        pin.forwardKinematics(self.pin_model, self.data, self.expand(q))
        return np.array([self.data.oMi[k].homogeneous for k in self.jid])

    def com(self, q) -> np.ndarray:
        """Centre of mass (3,)."""
        return np.array(pin.centerOfMass(self.pin_model, self.data, self.expand(q)))

    def jacobian(self, q, body: int, point) -> np.ndarray:
        """LOCAL_WORLD_ALIGNED frame Jacobian (6, nv) of a point fixed in ``body``."""
        pm = self.pin_model.copy()
        frame = pin.Frame(
            "probe",
            self.jid[body],
            pin.SE3(np.eye(3), np.asarray(point, dtype=float)),
            pin.FrameType.OP_FRAME,
        )
        fid = pm.addFrame(frame)
        data = pm.createData()
        J = pin.computeFrameJacobian(pm, data, self.expand(q), fid, pin.LOCAL_WORLD_ALIGNED)
        return J[:, self.cols]
