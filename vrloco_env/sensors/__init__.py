"""Sensor models: the head IMU (:mod:`.imu`) and the Kinect v2 (:mod:`.kinect`)."""
