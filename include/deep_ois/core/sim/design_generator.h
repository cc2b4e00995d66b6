// The design generator: one stabiliser design (core/sim/stabiliser_design.h) per seed, structure
// and parameters drawn from a family far wider than the learned model's hand-written chain, for
// measuring the lens model on stabilisers no one listed.
//
// Seeds are split once and for all: seeds with seed % 5 == 0 (20 % of any run of consecutive
// seeds) are held out from every decision (training, model choice, tuning) and reported apart.
#pragma once

#include <cstdint>

#include "deep_ois/core/sim/stabiliser_design.h"

namespace deep_ois {
namespace sim {

enum class DesignSplit { kTraining, kHeldOut };

// kHeldOut for seed % 5 == 0, kTraining otherwise.
DesignSplit designSplit(std::uint32_t seed);
const char* toString(DesignSplit split);  // "training" or "held_out"

// The design of `seed`: the same on every machine (portable random numbers, one stream per stage,
// so a change to one stage's draw leaves the others). Always valid (validate() is empty).
//
// How the family is drawn (probabilities per design):
//  - estimator class: each of designClasses() with 1/5; centring corner / bandwidth log-uniform
//    0.1-2 Hz; excursion-dependent centring 35 %;
//  - gyro misaligned (roll +-15 deg, tilt and pan +-3 deg) 50 %; loop rate 4 kHz (continuous)
//    40 %, 2 kHz, 1 kHz, 500 Hz 20 % each, latest or averaged sampling 50 %;
//  - mode detection none 50 %, release 25 %, hold 25 %; gain scheduled 30 %;
//  - stroke box, ellipse, soft box, soft ellipse 25 % each; symmetric 50 %, x and y differ 25 %,
//    every direction its own 25 %; anti-windup none, clamp, back-calculation 1/3 each;
//  - quantised 40 %, transport delay 40 %; actuator first order 35 %, slew-limited 30 %,
//    stiction 30 %; Hall nonlinearity 50 %, Hall noise 50 %.
StabiliserDesign generateDesign(std::uint32_t seed);

}  // namespace sim
}  // namespace deep_ois
