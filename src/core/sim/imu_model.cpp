#include "deep_ois/core/sim/imu_model.h"
