"""EKF-SLAM with range-bearing landmarks (slam-ekf.txt §3-4) and the Victoria Park loader."""
