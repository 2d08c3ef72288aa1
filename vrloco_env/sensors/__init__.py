"""Sensor models: the head IMU (:mod:`.imu`), the Kinect v2 (:mod:`.kinect`) and seed 004's
helmet camera seeing wall landmarks (:mod:`.head_camera`)."""
