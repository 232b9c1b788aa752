"""EKF-SLAM with range-bearing landmarks (slam-ekf.txt §3-5) and the Victoria Park loader.

Modules: ``models`` (Ackermann and unicycle motion models, range-bearing observation and
its inverse, all with Jacobians), ``ekf`` (the joint-state filter), ``association``
(gating, nearest neighbour, tentative landmarks), ``jcbb`` (joint compatibility),
``service`` (the message-level API: :class:`LandmarkSlam`), ``victoria_park`` (loader).
"""

from mapping.slam.ekf import EkfSlam
from mapping.slam.models import AckermannGeometry, AckermannModel, UnicycleModel
from mapping.slam.service import LandmarkSlam, SlamConfig, SlamStats

__all__ = [
    "AckermannGeometry",
    "AckermannModel",
    "EkfSlam",
    "LandmarkSlam",
    "SlamConfig",
    "SlamStats",
    "UnicycleModel",
]
