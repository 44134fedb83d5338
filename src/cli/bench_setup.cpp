// The built-in scene's flags, shared by fillgs bench and fillgs run (bench_setup.hpp).
#include "bench_setup.hpp"

namespace fillgs::cli {

BenchSetup bench_setup(const SetupFlags& s, const Invocation& in) {
  BenchSetup b;
  ExperimentOptions& e = b.scene;
  if (s.smoke) e.width = 64, e.height = 48, e.frames = 6, e.backbone_iterations = 150;
  if (in.given("--width")) e.width = s.width;
  if (in.given("--height")) e.height = s.height;
  if (in.given("--frames")) e.frames = s.frames;
  if (in.given("--backbone-iterations")) e.backbone_iterations = s.backbone_iterations;
  FinetuneOptions& f = b.finetune;
  f.iterations = in.given("--iterations") ? s.iterations : s.smoke ? 60 : f.iterations;
  f.select_every = in.given("--select-every") ? s.select_every : s.smoke ? 30 : f.select_every;
  f.train = fine_tune_schedule(f.iterations, motion_rates(in, s.rates));
  f.select.time_stride = s.time_stride;
  f.select.seed = 1;
  return b;
}

void add_setup_flags(CLI::App& app, SetupFlags& s, bool sizes) {
  add_flag(app, "--smoke", s.smoke, "a small, fast version (64x48, 6 frames, short runs)");
  if (sizes) {
    add_number(app, "--width", s.width, "image width of the built-in scene (0: the rig's, 160; technicolor 192; smoke 64)", at_least(0));
    add_number(app, "--height", s.height, "image height (0: the rig's, 120; technicolor 102; smoke 48)", at_least(0));
    add_number(app, "--frames", s.frames, "frames of the video (smoke 6)", at_least(2));
    add_number(app, "--backbone-iterations", s.backbone_iterations, "training iterations of the backbone (smoke 150)", at_least(1));
    add_number(app, "--iterations", s.iterations, "fine-tuning iterations (smoke 60)", at_least(1));
    add_number(app, "--select-every", s.select_every, "a selection round every M iterations (smoke 30)", at_least(1));
    add_number(app, "--time-stride", s.time_stride, "starting-view priority on every k-th frame only", at_least(1));
  }
  add_motion_rate_flags(app, s.rates);
}

}  // namespace fillgs::cli
