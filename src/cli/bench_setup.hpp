#pragma once
// The built-in scene's flags, shared by fillgs bench and fillgs run.
#include "options.hpp"
#include "fillgs/experiment/experiment.hpp"
#include "fillgs/method/finetune.hpp"

namespace fillgs::cli {

/// The built-in scene's size and the fine-tuning's counts, shared by bench and run; --smoke
/// shrinks the defaults.
struct SetupFlags {
  bool smoke = false;
  int width = ExperimentOptions().width, height = ExperimentOptions().height, frames = ExperimentOptions().frames;
  int backbone_iterations = ExperimentOptions().backbone_iterations;
  int iterations = FinetuneOptions().iterations, select_every = FinetuneOptions().select_every, time_stride = 1;
  MotionRateFlags rates;
};

struct BenchSetup {
  ExperimentOptions scene;
  FinetuneOptions finetune;
};

/// The scene and fine-tuning options the flags given ask for.
BenchSetup bench_setup(const SetupFlags& s, const Invocation& in);
/// --smoke, and with `sizes` the scene's size and the counts; the fine-tuning rates.
void add_setup_flags(CLI::App& app, SetupFlags& s, bool sizes);

}  // namespace fillgs::cli
