// Filled in by the implementer of imu_model.
