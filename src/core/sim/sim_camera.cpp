#include "deep_ois/core/sim/sim_camera.h"
