#include "deep_ois/core/sim/camera_motion.h"
