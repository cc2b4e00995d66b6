#pragma once

#include <Eigen/Core>

namespace deep_ois {

// exp(M) of a 3x3 matrix by scaling and squaring with a Taylor series (to double precision): the
// exact discretisation of a second-order actuator held over one step (the model's lens actuator and
// the simulator's generated designs use the same one).
Eigen::Matrix3d matrixExponential(const Eigen::Matrix3d& M);

}  // namespace deep_ois
