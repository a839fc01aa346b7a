// The apparel moves the same way at every output frame rate: the learned module steps at the rate it was trained
// at (kApparelStepFps) and the output is interpolated between its steps; the PMX physics steps at a fixed substep
// and its lead-in lasts as long at every rate. Exact on a tiny untrained model, measured on the shipped one.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "data_tools/formats/dataset_file.h"
#include "data_tools/formats/pmx_export.h"
#include "infer/runtime_torch.h"
#include "tests/data_tools/builder/pmx_humanoid.h"
#include "tests/infer/runtime_fixture.h"
#include "tests/test_support.h"

namespace amt {
namespace {

namespace fs = std::filesystem;

struct Frames {
  std::vector<MatrixX3f> frames;
  std::vector<uint8_t> apparel;
};

Frames read_run(const std::string& path) {
  Frames run;
  const DatasetReader reader(path);
  const ClipInfo clip = reader.clip_info(reader.clip_names().at(0));
  run.apparel = reader.read_character(clip.character).apparel_mask;
  for (int t = 0; t < clip.num_frames; ++t) run.frames.push_back(reader.read_vertices(clip.name, t, 1));
  return run;
}

// Runs `amt animate` with `args` into dir/out at `fps` for `frames` frames on one thread.
Frames animate_run(const fs::path& dir, std::vector<std::string> args, int fps, int frames) {
  const std::string out = "run_" + std::to_string(fps) + ".h5";
  args.insert(args.begin(), "animate");
  for (const std::string& a :
       {std::string("--fps"), std::to_string(fps), std::string("--frames"), std::to_string(frames),
        std::string("--out"), out, std::string("--threads"), std::string("1"), std::string("--quiet")}) {
    args.push_back(a);
  }
  const test::CommandResult r =
      test::run_command("cd '" + dir.string() + "' && " + test::shell_command(AMT_BINARY, args));
  EXPECT_EQ(r.status, 0) << r.err;
  if (r.status != 0) return {};
  return read_run((dir / out).string());
}

// The same clip through `amt animate` with `args` at 30 fps (40 frames) and at 60 fps (79 frames), over apparel
// vertices: `between`, the mean distance between the 30 fps run's frame t and the 60 fps run's frame 2 t (the same
// time); `odd`, the mean distance of the 60 fps run's frame 2 t + 1 from the middle of the 30 fps frames t and t + 1;
// `moved`, the mean distance an apparel vertex travels per 30 fps frame.
struct Agreement {
  double between = 0, odd = 0, moved = 0;
};

Agreement rates_agreement(const fs::path& dir, const std::vector<std::string>& args, const char* what) {
  const Frames a = animate_run(dir, args, 30, 40), b = animate_run(dir, args, 60, 79);
  Agreement g;
  EXPECT_EQ(a.frames.size(), 40u);
  EXPECT_EQ(b.frames.size(), 79u);
  if (a.frames.size() != 40u || b.frames.size() != 79u) return g;
  int64_t count = 0, pairs = 0;
  for (size_t t = 0; t < a.frames.size(); ++t) {
    for (Eigen::Index i = 0; i < a.frames[t].rows(); ++i) {
      if (!a.apparel[size_t(i)]) continue;
      g.between += (a.frames[t].row(i) - b.frames[2 * t].row(i)).norm();
      ++count;
      if (t == 0) continue;
      g.moved += (a.frames[t].row(i) - a.frames[t - 1].row(i)).norm();
      g.odd += (0.5f * (a.frames[t].row(i) + a.frames[t - 1].row(i)) - b.frames[2 * t - 1].row(i)).norm();
      ++pairs;
    }
  }
  g.between /= double(std::max<int64_t>(count, 1));
  g.moved /= double(std::max<int64_t>(pairs, 1)), g.odd /= double(std::max<int64_t>(pairs, 1));
  std::cout << what << ": apparel " << 100.0 * g.between << " cm apart at common times between 30 and 60 fps, 60 fps "
            << "frames between them " << 100.0 * g.odd << " cm from the middle, moving " << 100.0 * g.moved
            << " cm a frame\n";
  return g;
}

// At 60 fps the untrained module still steps 30 times a second: every even output frame is the 30 fps run's frame
// at the same time (the same model step, the same pose), and an odd frame lies between its neighbours.
TEST(FrameRate, At60FpsTheLearnedApparelStepsAt30AndTheEvenFramesAreThe30FpsRun) {
  const test::RuntimeFixture f = test::make_runtime_fixture("frame_rate_exact");
  AnimateOptions o30 = test::runtime_options(f, (f.dir / "a30.h5").string());
  o30.bind_path = "none";
  const AnimateSummary s30 = animate(o30);
  AnimateOptions o60 = o30;
  o60.out = (f.dir / "a60.h5").string();
  o60.playback.fps = 60.0f;
  const AnimateSummary s60 = animate(o60);

  const Frames a = read_run(o30.out), b = read_run(o60.out);
  const int T = s30.frames;
  ASSERT_GT(T, 10);
  EXPECT_EQ(s30.apparel_steps, T);
  EXPECT_EQ(s60.frames, 2 * T - 1);  // resampling keeps every frame inside the clip
  EXPECT_EQ(s60.apparel_steps, T);
  EXPECT_NE(
      describe(s60).find("apparel module: " + std::to_string(T) +
                         " steps at 30 steps per second (the rate it was trained at), interpolated to the 60 fps"),
      std::string::npos)
      << describe(s60);
  EXPECT_EQ(describe(s30).find("interpolated"), std::string::npos);
  ASSERT_EQ(b.frames.size(), size_t(2 * T - 1));
  double worst_even = 0, worst_odd = 0, step = 0;
  for (int k = 0; k < T; ++k) {
    worst_even = std::max(worst_even, double((b.frames[size_t(2 * k)] - a.frames[size_t(k)]).cwiseAbs().maxCoeff()));
    if (k + 1 == T) continue;
    const MatrixX3f mid = 0.5f * (a.frames[size_t(k)] + a.frames[size_t(k + 1)]);
    worst_odd = std::max(worst_odd, double((b.frames[size_t(2 * k + 1)] - mid).rowwise().norm().maxCoeff()));
    step = std::max(step, double((a.frames[size_t(k + 1)] - a.frames[size_t(k)]).rowwise().norm().maxCoeff()));
  }
  EXPECT_LT(worst_even, 1e-5) << "metres";
  EXPECT_GT(step, 0.005);                         // the walk moves the mesh by centimetres a frame ...
  EXPECT_LT(worst_odd, 0.25 * step) << "metres";  // ... and an odd frame lies near the middle of its neighbours
}

// The shipped model on a procedural character under a CMU walk, at 30 and 60 fps: the apparel agrees at common
// times (the same model steps) while it moves centimetres a frame, and the frames between lie near the middle (a
// module that stepped once per output frame swings twice as fast at 60 fps and fails both).
TEST(FrameRate, ShippedLearnedApparelAgreesAt30And60Fps) {
  const std::string model = fs::path(AMT_ASSET_DIR).parent_path().string() + "/models/pretrained";
  const Agreement g =
      rates_agreement(test::temp_dir("frame_rate_shipped"),
                      {"--character", "generated:3", "--motion", std::string(AMT_ASSET_DIR) + "/mocap/cmu/02_01.bvh",
                       "--model", model, "--bind", "none"},
                      "learned apparel");
  EXPECT_GT(g.moved, 0.005);
  EXPECT_LT(g.between, 0.001) << "metres";
  EXPECT_LT(g.odd, 0.25 * g.moved) << "metres";
}

// A PMX model's own physics at 30 and 60 fps: it steps on a 120 Hz clock whatever the output rate, so the bodies
// agree at common times, and the 60 fps frames between (steps of their own) lie near the middle.
TEST(FrameRate, PmxPhysicsAgreesAt30And60Fps) {
  const fs::path dir = test::temp_dir("frame_rate_pmx");
  write_pmx(test::pmx_humanoid(), (dir / "humanoid.pmx").string());
  const Agreement g = rates_agreement(dir,
                                      {"--character", "humanoid.pmx", "--motion",
                                       std::string(AMT_ASSET_DIR) + "/mocap/cmu/02_01.bvh", "--apparel", "physics"},
                                      "PMX physics");
  EXPECT_GT(g.moved, 0.005);
  EXPECT_LT(g.between, 0.001) << "metres";
  EXPECT_LT(g.odd, 0.25 * g.moved) << "metres";
}

}  // namespace
}  // namespace amt
