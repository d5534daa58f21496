"""Robots: self- and environment collision of a URDF robot for batches of configurations.

    URDF (yourdfpy) -> links' collision meshes + joints in tree order
    configurations (C, J) -> link transforms (C, L, 4, 4) -> body transforms (C, B, 4, 4)
    pairs to check (every pair of bodies on different links, less the allowed-collision
    matrix; robot against environment) -> one query of a batch: a copy per configuration of
    the bodies those pairs name (prepared once: :meth:`pycinder.scene.PreparedBodies.copies`),
    its only candidates each configuration's pairs to check, culled by their world boxes
    -> (C,) bool, and pairs when asked

A :class:`Robot` is read from a URDF with :meth:`Robot.from_urdf` (the ``robot`` extra brings
yourdfpy). Its collision geometry is taken as the URDF gives it: meshes as they are (an open mesh
is tested as a surface, see :mod:`pycinder.request`), boxes, cylinders and spheres as meshes.
Forward kinematics runs on the GPU for every batch (pass K1, :mod:`pycinder.robot.k1_kinematics`;
:data:`~pycinder.robot.robot.GPU_FRONT_FROM`), so that a configuration's poses, and its pairs,
do not depend on the batch it is checked in; a configuration whose joint values K1's error
estimate does not hold for (a prismatic joint past its travel) takes the host's float64
kinematics, vectorised over configurations in NumPy, in any batch.

Pairs that need no check are kept in an :class:`AllowedCollisionMatrix`, made the way MoveIt's
Setup Assistant makes it (:meth:`Robot.compute_allowed_collisions`: adjacent links, pairs in
collision in the default configuration, pairs always and never in collision over sampled
configurations) and written and read as an SRDF's ``<disable_collisions>`` elements, so that a
MoveIt user's SRDF is honoured as given.

Disallowed pairs are never put on the GPU: a batched query holds a copy of the bodies per
configuration, and its only candidate pairs are each configuration's checked pairs, culled by their
world boxes (no sweep runs).

Padding is MoveIt's: the robot checked against the environment is the padded robot (each link grown
by its padding), and self-collision is checked with the unpadded robot, as MoveIt's
``PlanningScene`` does. A link (or an attached object named in a padding dict) and an environment
body collide when their surfaces are closer than the link's padding. It runs through the clearance
mode (:mod:`pycinder.focused.modes.clearance`) at the largest padding, and each pair is kept by its
own: a pair closer than its padding is always reported, one more than its padding plus an eighth of
the largest padding apart never is.
"""

from .acm import REASONS, AllowedCollisionMatrix, AlwaysCollidingWarning, matrix_from_samples
from .model import JOINT_TYPES, Body, Environment, RobotModel
from .robot import (DEFAULT_BODIES_PER_QUERY, FIRST_BATCH, GPU_BODIES_PER_QUERY, QUERY_SECONDS,
                    Robot)

__all__ = ["DEFAULT_BODIES_PER_QUERY", "FIRST_BATCH", "GPU_BODIES_PER_QUERY", "JOINT_TYPES",
           "QUERY_SECONDS", "REASONS",
           "AllowedCollisionMatrix", "AlwaysCollidingWarning", "Body", "Environment", "Robot",
           "RobotModel", "matrix_from_samples"]
