"""Sensor models: the head IMU (:mod:`.imu`), the Kinect v2 (:mod:`.kinect`) and the helmet-tracking
paper's helmet camera seeing wall landmarks (:mod:`.head_camera`)."""
