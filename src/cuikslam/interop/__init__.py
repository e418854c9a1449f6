"""Results and logs in the tools SLAM users already have: evo, g2o and GTSAM.

- :mod:`.estimate`: one point per pose and landmark from a hypothesis (its witness or box
  centres) or a truth file, and GTSAM's keys for them;
- :mod:`.tum`: TUM trajectory files (``evo_traj``, ``evo_ape``);
- :mod:`.g2o`: g2o graph files (``VERTEX_SE2``, ``VERTEX_XY``, ``EDGE_SE2``, ...);
- :mod:`.gaussian`: the log's intervals read as Gaussians, as the back ends take them;
- :mod:`.gtsam`: a log and hypothesis as a ``gtsam.NonlinearFactorGraph`` and
  ``gtsam.Values`` (needs ``pip install "cuikslam[interop]"``);
- :mod:`.check`: which poses and landmarks of an estimate lie outside the boxes
  (:func:`cuikslam.check_estimate`).

Only :mod:`.gtsam` imports GTSAM; everything else needs nothing beyond cuikslam.
"""
