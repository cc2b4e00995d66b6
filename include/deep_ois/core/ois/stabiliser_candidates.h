// Choosing a camera's stabiliser model by measurement: the physical chain fitted by
// core/ois/stabiliser_fit.h is the prior and the fallback; learned dynamics on top of it are
// candidates, each scored on the held-out recordings, and the best is kept.
//
// Candidates (cheap enough for the live budget: microseconds per frame at the gyro rate):
//  - "physical": the fitted chain alone;
//  - "physical + linear residual": plus the bank of leaky rate integrals (what fitStabiliser
//    returns);
//  - the chain with a better structure, refitted (refitStabiliserStructure): an integrator held at
//    the end stop (anti-windup), a re-centring corner that grows with the excursion, both; the
//    stroke in the actuator's own axes with a cross-coupling after the actuator (a turned or
//    coupled mount); a soft stroke (stroke x tanh(u / stroke)) instead of an end stop, alone and
//    with the excursion-dependent re-centring;
//  - then, each by ridge regression on what that leaves (StabiliserParameters::nonlinear_features):
//    a learned higher-order linear filter of the rate (rate_bank_v1); nonlinear functions of the
//    chain's state (excursion_v1: saturations of the command, its excursion against the stroke,
//    leaky integrals of the excursion-weighted command), for stabilisers whose re-centring, stroke
//    or estimator the chain does not name; and both (excursion_rate_v1).
// Pure C++/Eigen: no ROS.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "deep_ois/core/ois/lens_dynamics_network.h"
#include "deep_ois/core/ois/stabiliser_fit.h"

namespace deep_ois {

// `base` plus a nonlinear residual (feature set `feature_set`) fitted by ridge regression (weight
// `ridge` relative to each feature's energy, Huber weights as options.huber_px) on the lens
// motion `base` leaves in `recordings`. Throws std::invalid_argument when no observation is usable.
StabiliserParameters fitNonlinearResidual(const StabiliserParameters& base,
                                          const std::vector<StabiliserFitRecording>& recordings,
                                          const StabiliserFitOptions& options,
                                          const std::string& feature_set = "excursion_v1",
                                          double ridge = 1e-4);

// A stabiliser model with a name for messages ("fit", "no lens motion", "generic", ...).
struct ModelCandidate {
  std::string name;
  StabiliserParameters parameters;
};

// Which candidates stabiliserCandidates builds besides the physical chain and its linear bank.
struct StabiliserCandidateKinds {
  bool structural = true;        // the refitted structural variants (an LM refit each)
  // Levenberg-Marquardt iterations of each structural refit (0: the fit options' iterations). The
  // refits start from the fitted chain, so fewer suffice where time counts (the online learner).
  int structural_iterations = 0;
  bool learned_features = true;  // the ridge-fitted residuals (one pass over the data each)
  // The generic learned lens dynamics (core/ois/lens_dynamics_network.h), pretrained on generated
  // designs: adapted to the camera (its conditioning vector; then with a 2x2 map of its lens too),
  // the chain off. Null: not a candidate.
  std::shared_ptr<const LensDynamicsNetwork> lens_dynamics;
  int lens_dynamics_iterations = 12;  // Levenberg-Marquardt iterations of each adaptation
  // The adaptation with the lens map too (a second adaptation: about as costly as the first); the
  // output layer is then refitted on it (one pass), else on the conditioning's.
  bool lens_dynamics_map = true;
};

// The candidates built from a physical fit (a fitStabiliser result), simplest first, unscored:
// "physical", "physical + linear residual" (when the fit has a bank), then the kinds asked for.
// A variant whose refit finds no usable lens motion is left out (the simpler ones stand).
std::vector<ModelCandidate> stabiliserCandidates(const StabiliserFitResult& fit,
                                                 const std::vector<StabiliserFitRecording>& training,
                                                 const StabiliserFitOptions& options,
                                                 const StabiliserCandidateKinds& kinds = {});

struct StabiliserCandidate {
  std::string name;
  StabiliserParameters parameters;
  StabiliserScore training;  // scoreStabiliser (core/ois/stabiliser_fit.h)
  StabiliserScore held_out;  // observations 0 without held-out recordings
};

struct StabiliserSelection {
  std::vector<StabiliserCandidate> candidates;  // simplest first
  std::size_t kept = 0;
  std::string reason;  // one sentence: why candidates[kept] ("kept 'NAME': " + figures)
  std::string figures;  // the figures that chose it ("held-out lens-motion RMS 0.41 px, ...")
};

// Builds (stabiliserCandidates, `kinds`) and scores the candidates from the physical fit. Kept: the lowest held-out RMS (the
// training RMS when there are no held-out recordings: then said in the reason), unless a simpler
// candidate is within `simpler_within` (relative) of it, which is kept instead.
StabiliserSelection selectStabiliser(const StabiliserFitResult& fit,
                                     const std::vector<StabiliserFitRecording>& training,
                                     const std::vector<StabiliserFitRecording>& held_out,
                                     const StabiliserFitOptions& options,
                                     double simpler_within = 0.01,
                                     const StabiliserCandidateKinds& kinds = {});

}  // namespace deep_ois
