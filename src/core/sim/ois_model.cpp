#include "deep_ois/core/sim/ois_model.h"
