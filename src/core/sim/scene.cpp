#include "deep_ois/core/sim/scene.h"
