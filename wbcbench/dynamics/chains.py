"""Split of a floating-base tree into virtual, constraint and unconstrained chains.

RC-LQP paper §3.1 (Fig. 1): the *virtual chain* is the floating base (6 velocity coordinates);
the *constraint chain* holds every joint on a path from the base to a contact frame; the
*unconstrained chains* are the subtrees left over (arms, neck, a swing leg, ...). A joint on a
constraint-chain path that an unconstrained subtree also hangs from (e.g. a waist when the base is
the torso and one hand is in contact) stays in the constraint chain: it is the "overlapping"
joint of the paper, listed here as ``overlap`` of the chain that needs it.

Unconstrained subtrees that hang from the same body are merged into one chain: the base's and
the constraint chain's equations see a subtree only through its momentum, and subtrees on one
body add their momenta, so one 6-D centroidal coordinate describes them together (single
support: the upper body and the swing leg become one 27-DoF chain on TOCABI). A merged chain of
six DoF or fewer is not worth compressing into six coordinates: its joints are ``kept`` as plain
coordinates of the reduced model.

Everything is expressed as velocity-index arrays into ``v`` (Pinocchio order, base first); the
selection matrices of the paper are ``np.eye(n)[idx]``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from wbcbench.errors import ModelError

#: a chain with at most this many DoF is kept joint by joint (its centroid has 6 coordinates)
CENTROID_DIM = 6


def _velocity_indices(model: pin.Model, joints: Sequence[int]) -> np.ndarray:
    """Velocity indices (sorted) of Pinocchio joints ``joints``."""
    idx = [np.arange(model.idx_vs[j], model.idx_vs[j] + model.nvs[j]) for j in joints]
    return np.sort(np.concatenate(idx)).astype(int) if idx else np.zeros(0, dtype=int)


@dataclass(frozen=True)
class UnconstrainedChain:
    """One unconstrained chain: the subtrees hanging from one body off the constraint chain.

    Attributes:
        name: ``<parent body>:<root joint>+<root joint>...``.
        parent_joint: Pinocchio joint id of the body the subtrees hang from (1 = the base).
        root_joints: Pinocchio joint ids of the subtree roots.
        joints: every Pinocchio joint id of the chain.
        idx: velocity indices of the chain (n_uc,).
        overlap: velocity indices of constraint-chain joints between the base and the chain
            (the paper's overlapping joints, e.g. a waist), possibly empty.
    """

    name: str
    parent_joint: int
    root_joints: tuple[int, ...]
    joints: tuple[int, ...]
    idx: np.ndarray
    overlap: np.ndarray

    @property
    def dof(self) -> int:
        return int(self.idx.size)


@dataclass(frozen=True)
class ChainSplit:
    """The three kinds of chains of one robot for one set of contact frames.

    Attributes:
        n: number of generalized velocities (6 + k).
        contact_frames: the frames that define the constraint chain.
        virtual: velocity indices of the floating base (6,).
        constraint: velocity indices of the constraint chain (n_cc,).
        kept: velocity indices of unconstrained joints kept as plain coordinates (chains of six
            DoF or fewer), possibly empty.
        chains: the unconstrained chains compressed into 6-D centroidal coordinates.
    """

    n: int
    contact_frames: tuple[str, ...]
    virtual: np.ndarray
    constraint: np.ndarray
    kept: np.ndarray
    chains: tuple[UnconstrainedChain, ...]

    @property
    def unconstrained(self) -> np.ndarray:
        """Velocity indices of every compressed chain, chain after chain (n_uc,)."""
        if not self.chains:
            return np.zeros(0, dtype=int)
        return np.concatenate([c.idx for c in self.chains])

    @property
    def plain(self) -> np.ndarray:
        """Coordinates the reduced model keeps as they are: virtual, constraint, kept."""
        return np.concatenate([self.virtual, self.constraint, self.kept])

    @property
    def n_reduced(self) -> int:
        """Dimension n_r of the reduced model: plain coordinates + 6 per chain."""
        return int(self.plain.size + CENTROID_DIM * len(self.chains))

    def selection(self, idx: np.ndarray) -> np.ndarray:
        """Selection matrix (len(idx), n) of the velocity indices ``idx`` (S_vc, S_cc, S_uc)."""
        return np.eye(self.n)[idx]

    def describe(self, model: pin.Model) -> str:
        """One line per chain kind, with joint names (for logs and reports)."""

        def names(idx: np.ndarray) -> str:
            joints = [model.names[j] for j in range(2, model.njoints) if model.idx_vs[j] in idx]
            return ", ".join(joints) or "-"

        lines = [
            f"virtual: base ({self.virtual.size})",
            f"constraint ({self.constraint.size}): {names(self.constraint)}",
        ]
        if self.kept.size:
            lines.append(f"kept ({self.kept.size}): {names(self.kept)}")
        for c in self.chains:
            lines.append(f"unconstrained {c.name} ({c.dof}): {names(c.idx)}")
        return "\n".join(lines)


def split_chains(model: pin.Model, contact_frames: Sequence[str]) -> ChainSplit:
    """Split ``model`` (a free-flyer root, joint 1) for the given contact frames.

    Raises:
        ModelError: the root is not a 6-DoF free flyer, or a contact frame does not exist.
    """
    if model.njoints < 2 or model.nvs[1] != 6 or model.idx_vs[1] != 0:
        raise ModelError("chain split: the model's first joint must be a 6-DoF floating base")
    names = [f.name for f in model.frames]
    contact_joints: set[int] = set()
    for frame in contact_frames:
        # a site (OP_FRAME) of that name, else a body, as Robot.frame_id
        kind = next(
            (t for t in (pin.FrameType.OP_FRAME, pin.FrameType.BODY) if model.existFrame(frame, t)),
            None,
        )
        if kind is None:
            raise ModelError(
                f"chain split: no frame {frame!r}; valid frames: {', '.join(sorted(set(names)))}"
            )
        parent = model.frames[model.getFrameId(frame, kind)].parentJoint
        contact_joints.update(j for j in model.supports[parent] if j >= 2)

    constraint = sorted(contact_joints)
    unconstrained = [j for j in range(2, model.njoints) if j not in contact_joints]
    # subtree roots: unconstrained joints whose parent is the base or a constraint-chain joint
    roots = [j for j in unconstrained if model.parents[j] not in unconstrained]
    by_parent: dict[int, list[int]] = {}
    for j in roots:
        by_parent.setdefault(int(model.parents[j]), []).append(j)

    chains: list[UnconstrainedChain] = []
    kept: list[int] = []
    for parent, group in sorted(by_parent.items()):
        joints = sorted(int(i) for r in group for i in model.subtrees[r])
        idx = _velocity_indices(model, joints)
        if idx.size <= CENTROID_DIM:
            kept.extend(joints)
            continue
        overlap = [j for j in model.supports[parent] if j >= 2]
        body = "base" if parent == 1 else model.names[parent]
        chains.append(
            UnconstrainedChain(
                name=f"{body}:{'+'.join(model.names[r] for r in group)}",
                parent_joint=parent,
                root_joints=tuple(group),
                joints=tuple(joints),
                idx=idx,
                overlap=_velocity_indices(model, overlap),
            )
        )
    return ChainSplit(
        n=int(model.nv),
        contact_frames=tuple(contact_frames),
        virtual=np.arange(6),
        constraint=_velocity_indices(model, constraint),
        kept=_velocity_indices(model, sorted(kept)),
        chains=tuple(chains),
    )
