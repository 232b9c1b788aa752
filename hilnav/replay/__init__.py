"""``hilnav replay``: a log's device messages through the services again, deterministically.

``replayer`` (the replay loop and its report), ``resolve`` (robot, config and pipeline of a
replay), ``devices`` (device topics and the codecs that decode raw bytes again),
``landmark_slam`` (the pipeline of landmark data sets: EKF-SLAM).
"""
