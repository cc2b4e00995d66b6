#include "deep_ois/core/sim/rolling_shutter_renderer.h"
