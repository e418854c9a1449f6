"""Certified consistency of a hypothesis: a witness point found numerically, verified rigorously.

Narrowing can prove a hypothesis *impossible* (its boxes contract to empty) but never that
it is *possible*. This package does the latter: it looks for one world (poses and
landmarks) that satisfies every measured interval of the log under the hypothesis'
assignment, with a local optimiser, and then verifies that point with the interval kernel
(:mod:`cuikslam.interval`), so that a ``True`` answer is a proof.

It certifies the hypotheses of any solve, known correspondence too, so it is a layer of
its own: it runs after the search (:mod:`cuikslam.hypotheses`, whose former subpackage
``cuikslam.hypotheses.witness`` re-exports it) and imports nothing of it; it reads and
marks the types of :mod:`cuikslam.outcome`, and never imports the presentation layer
(the ``results`` package: files, tables, figures).

The stages, one module each:

* :mod:`.model`: :class:`HypothesisModel`, the parametrisation of a hypothesis (an anchor
  pose, a turn and distance per tree odometry, a ``(dx, dy, dtheta)`` per tree relative
  pose and per sensor offset, landmark positions) and its checks (every other measured
  interval, loop closures, the sensor's negative information), evaluated in floating point
  for the optimisers; :mod:`._kinematics` builds the tree of poses and sensor poses and
  runs it in floating point and in interval arithmetic;
* :mod:`.verify`: :func:`verify_witness`, the rigorous decision: interval forward
  kinematics from a parameter point, and a Poincaré–Miranda box around it when loop
  closures make equalities;
* :mod:`._world`: the same hypothesis in its *world form* (every frame and landmark a
  parameter, every motion a check: a sparse Jacobian), where the search minimises;
* :mod:`.find`: :func:`find_witness`, the local search for a point that verifies;
* :mod:`.certification`: :func:`certify`, which runs it on every hypothesis of a
  :class:`~cuikslam.outcome.solution.Solution`, sharing one budget;
* :mod:`.fit`: :func:`fit_hypotheses`, the least-squares cost of each hypothesis' best
  world, which ranks equally parsimonious hypotheses;
* :mod:`.hull`: :func:`inner_hull`, the same machinery used to measure the exact solution
  set from inside (every point it keeps is verified), to judge how tight the narrowed
  boxes are.
"""

from cuikslam.witness.certification import certify
from cuikslam.witness.find import find_witness
from cuikslam.witness.fit import fit_hypotheses
from cuikslam.witness.hull import InnerHull, inner_hull
from cuikslam.witness.model import (
    AIM_FRACTION,
    MIN_MARGIN,
    HypothesisModel,
    WitnessPoint,
)
from cuikslam.witness.verify import verify_witness

__all__ = [
    "AIM_FRACTION",
    "MIN_MARGIN",
    "HypothesisModel",
    "InnerHull",
    "WitnessPoint",
    "certify",
    "find_witness",
    "fit_hypotheses",
    "inner_hull",
    "verify_witness",
]
