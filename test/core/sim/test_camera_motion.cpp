// Filled in by the implementer of camera_motion.
