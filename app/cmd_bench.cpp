// `amt bench`: speed and memory figures. Benchmarks print medians over repeats and never fail on
// timing; the README quotes their output together with the command that made it.
#include <omp.h>
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <functional>
#include <random>

#include "app/commands.h"
#include "data_tools/error.h"
#include "data_tools/geodesic.h"
#include "data_tools/lbs.h"
#include "data_tools/procedural_motion.h"
#include "data_tools/shapes.h"

namespace amt::app {

namespace {

struct BenchOptions {
  int vertices = 20000;
  int repeats = 30;
  std::vector<std::string> suites = {"lbs", "geodesic"};
};

// Median wall time in seconds of `repeats` calls of fn, after one warm-up call.
double median_seconds(int repeats, const std::function<void()>& fn) {
  fn();
  std::vector<double> times;
  for (int r = 0; r < repeats; ++r) {
    const auto start = std::chrono::steady_clock::now();
    fn();
    times.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  }
  std::nth_element(times.begin(), times.begin() + times.size() / 2, times.end());
  return times[times.size() / 2];
}

double peak_resident_mb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss / 1024.0;
}

// LBS throughput with 4 influences per vertex over frames of a walk.
void bench_lbs(const BenchOptions& o) {
  const Skeleton s = canonical_skeleton();
  const TriMesh mesh = capsule_character(s.rest_joints, s.parents, o.vertices);
  const int N = mesh.num_vertices(), J = s.num_joints();
  std::mt19937 rng(1);
  std::uniform_int_distribution<int> joint(0, J - 1);
  std::uniform_real_distribution<float> weight(0.05f, 1.0f);
  SparseWeights w;
  w.indices.resize(N, kMaxInfluences);
  w.weights.resize(N, kMaxInfluences);
  for (int i = 0; i < N; ++i) {
    for (int k = 0; k < kMaxInfluences; ++k) w.indices(i, k) = joint(rng), w.weights(i, k) = weight(rng);
    w.weights.row(i) /= w.weights.row(i).sum();
  }
  const Motion walk = walk_motion(30);
  std::vector<Transforms> frames;
  for (int t = 0; t < walk.num_frames(); ++t) frames.push_back(skinning_matrices(s, forward_kinematics(s, walk, t)));
  MatrixX3f out;
  int t = 0;
  const double seconds = median_seconds(o.repeats, [&] {
    linear_blend_skinning(mesh.V, w, frames[t], out);
    t = (t + 1) % static_cast<int>(frames.size());
  });
  std::printf("lbs       %6d vertices, 4 influences: median %.3f ms per frame, %.1f M vertices/s\n", N, 1e3 * seconds,
              N / seconds / 1e6);
}

// Geodesic matrix G (N x 22) of a capsule stand-in character (22 separate parts, bridged).
void bench_geodesic(const BenchOptions& o) {
  const Skeleton s = canonical_skeleton();
  const TriMesh mesh = capsule_character(s.rest_joints, s.parents, o.vertices);
  MatrixXfR G;
  const int repeats = std::max(3, o.repeats / 6);
  const double seconds = median_seconds(repeats, [&] { G = geodesic_distances(mesh.V, mesh.F, s.rest_joints); });
  AMT_CHECK(G.allFinite(), "bench: geodesic: expected finite distances");
  std::printf("geodesic  %6d vertices, %d joints, 22 parts: median %.1f ms per matrix (%d runs)\n",
              mesh.num_vertices(), s.num_joints(), 1e3 * seconds, repeats);
}

}  // namespace

void add_bench_command(CLI::App& app) {
  auto options = std::make_shared<BenchOptions>();
  auto* bench = app.add_subcommand("bench", "Speed and memory figures (medians over repeats)");
  bench->add_option("--vertices", options->vertices, "Vertices of the generated stand-in character")
      ->check(CLI::Range(100, 5000000))
      ->capture_default_str();
  bench->add_option("--repeats", options->repeats, "Timed repeats per figure")->check(CLI::Range(1, 100000))->capture_default_str();
  bench->add_option("--suite", options->suites, "Suites to run: lbs, geodesic")
      ->check(CLI::IsMember({"lbs", "geodesic"}))
      ->capture_default_str();
  add_threads_option(*bench);
  bench->callback([options] {
    std::printf("amt bench: %d threads\n", omp_get_max_threads());
    for (const std::string& suite : options->suites) {
      if (suite == "lbs") bench_lbs(*options);
      if (suite == "geodesic") bench_geodesic(*options);
    }
    std::printf("peak resident memory: %.0f MB\n", peak_resident_mb());
  });
}

}  // namespace amt::app
