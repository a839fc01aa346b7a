// `amt bench`: speed and memory figures. Benchmarks print medians over repeats and never fail on
// timing; the README quotes their output together with the command that made it.
#include <omp.h>
#include <sys/resource.h>

#include <unistd.h>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <functional>
#include <memory>
#include <random>

#include <ATen/ATen.h>
#include <c10/core/InferenceMode.h>
#include <torch/utils.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "amt/version.h"
#include "app/commands.h"
#include "app/repository.h"
#include "data_tools/builder/apparel.h"
#include "data_tools/builder/body_generator.h"
#include "data_tools/builder/open_parts.h"
#include "data_tools/builder/segmenter_augmentation.h"
#include "data_tools/formats/dataset_file.h"
#include "data_tools/garment/cloth_retarget.h"
#include "data_tools/geometry/error.h"
#include "data_tools/geometry/geodesic.h"
#include "data_tools/geometry/lbs.h"
#include "data_tools/geometry/lbs_torch.h"
#include "data_tools/geometry/procedural_motion.h"
#include "data_tools/geometry/retarget.h"
#include "data_tools/geometry/shapes.h"
#include "data_tools/geometry/threads.h"
#include "infer/glb_stream_writer.h"
#include "infer/runtime_benchmark_torch.h"
#include "infer/runtime_torch.h"
#include "models/joint_refiner.h"
#include "models/pipeline.h"
#include "models/skinning_overfit.h"
#include "train/samples.h"

namespace amt::app {

namespace {

struct BenchOptions {
  int vertices = 20000;
  int repeats = 30;
  std::vector<std::string> suites = {"lbs", "geodesic"};
  std::vector<int> runtime_sizes = {5000, 20000, 50000};
  std::vector<int> runtime_threads = {1, 2};
  int cloth_vertices = 12000;      // cloth suite: vertices of each generated body
  std::string model;               // empty: the repository's models/pretrained when found (app/repository.h)
  bool open_parts = false;         // runtime suite: the characters cut into open, overlapping parts (open_parts.h)
  bool artist_style = false;       // runtime suite: the characters remade artist-style (artist_style.h)
  bool segmenter_mask = false;     // runtime suite: the segmenter's apparel mask instead of the dressed character's
  bool reference_apparel = false;  // runtime suite: the global apparel form's network timed beside the model's
  bool refine = false;             // runtime suite: the refiner after the apparel module (amt animate --refiner)
  float strain_limit = kDefaultStrainLimit;  // runtime suite: amt animate --strain-limit
  std::vector<std::string> data;             // segmenter suite: dataset shards or folders
  std::string segmenter;                     // segmenter suite: checkpoint (empty: <model>/segmenter.ckpt)
  std::string split = "test";                // segmenter suite: the characters scored
};

// The calling thread's CPU time, seconds.
double thread_cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

// Medians over `repeats` calls of fn, after one warm-up call, in seconds: wall time, and the calling
// thread's CPU time (on a shared machine, the wall time less the time the thread waited for a core;
// meaningful for single-threaded work only).
struct MedianTimes {
  double wall = 0, cpu = 0;
};
MedianTimes median_times(int repeats, const std::function<void()>& fn) {
  fn();
  std::vector<double> wall, cpu;
  for (int r = 0; r < repeats; ++r) {
    const double cpu_start = thread_cpu_seconds();
    const auto start = std::chrono::steady_clock::now();
    fn();
    wall.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    cpu.push_back(thread_cpu_seconds() - cpu_start);
  }
  const auto median = [](std::vector<double>& v) {
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  return {median(wall), median(cpu)};
}

// Median wall time in seconds of `repeats` calls of fn, after one warm-up call.
double median_seconds(int repeats, const std::function<void()>& fn) {
  return median_times(repeats, fn).wall;
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
  std::printf("geodesic  %6d vertices, %d joints, 22 parts: median %.1f ms per matrix (%d runs)\n", mesh.num_vertices(),
              s.num_joints(), 1e3 * seconds, repeats);
}

// Training speed of the skinning predictor: the fixed overfit run of models/skinning_overfit.h (a 22-vertex
// bar, 500 AdamW steps through LBS, 1 thread), whose loss its unit test checks.
void bench_skinning(const BenchOptions& o) {
  set_thread_count(1);
  SkinningOverfit run;
  const int repeats = std::max(1, o.repeats / 10);
  const double seconds = median_seconds(repeats, [&] { run = overfit_skinning_on_a_bar(500); });
  std::printf(
      "skinning  overfit of f_s on a 22-vertex bar through LBS, %d AdamW steps, 1 thread: median %.2f s "
      "(%.2f ms per step, %d runs), L1 %.5f -> %.5f\n",
      run.steps, seconds, 1e3 * seconds / run.steps, repeats, run.initial_loss, run.final_loss);
}

// The shipped networks when `dir` holds them, else freshly initialised ones of the default options
// (seeded): the per-frame cost depends on the architecture, not on the weights.
ModelBundle bench_bundle(const std::string& given, std::string& what) {
  const std::string dir = !given.empty() ? given : find_repository_folder("models/pretrained");
  if (!dir.empty() && std::filesystem::exists(std::filesystem::path(dir) / kRefinerCheckpoint)) {
    what = "shipped model " + dir;
    return load_model_bundle(dir);
  }
  what = "freshly initialised networks of the default options (no checkpoints in " + dir + ")";
  torch::manual_seed(1);
  ModelBundle b;
  b.joint_names = canonical_joint_names();
  b.segmenter = ApparelSegmenter(ApparelSegmenterOptions{});
  b.skinning = SkinningPredictor(SkinningPredictorOptions{});
  b.apparel_dynamics = ApparelDynamicsNet(ApparelDynamicsOptions{});
  b.apparel_dynamics->freeze_normalizers();  // identity statistics: the cost is the same
  b.refiner = JointRefiner(JointRefinerOptions{});
  for (torch::nn::Module* m : std::initializer_list<torch::nn::Module*>{b.segmenter.get(), b.skinning.get(),
                                                                        b.apparel_dynamics.get(), b.refiner.get()}) {
    m->eval();
    for (auto& p : m->parameters()) p.set_requires_grad(false);
  }
  return b;
}

// The runtime (issue 6): generated dressed characters of about `size` vertices with ~30 % apparel,
// bind time, per-frame latency (median, p95) and its split, peak memory, on 1 and 2 threads. With
// --open-parts the characters are remade as real models are built (data_tools/builder/open_parts.h):
// a body of many open, overlapping parts with holes under the clothes and a hair cap, ~20 % apparel.
void bench_runtime(const BenchOptions& o) {
  std::string what;
  ModelBundle bundle = bench_bundle(o.model, what);
  std::printf("runtime   %s; apparel mask from %s; walk motion; %d timed frames after a %d-frame lead-in%s\n",
              what.c_str(), o.segmenter_mask ? "the segmenter" : "the dressed character (the GT-mask row)", o.repeats,
              kDefaultLeadInFrames, o.open_parts ? "; bodies of open, overlapping parts (--open-parts)" : "");
  for (const int size : o.runtime_sizes) {
    RuntimeBenchmarkOptions options;
    options.vertices = size;
    options.open_parts = o.open_parts;
    options.artist_style = o.artist_style;
    options.segmenter_mask = o.segmenter_mask;
    options.threads = o.runtime_threads;
    options.repeats = o.repeats;
    options.reference_apparel = o.reference_apparel;
    options.refine = o.refine;
    options.strain_limit = o.strain_limit;
    const RuntimeFigures r = measure_runtime(bundle, options);
    const int N = r.vertices;
    std::printf(
        "runtime   %6d vertices (%d apparel, %.0f %%; as built %d, %.0f %%), %d faces: %s; bind %.2f s (%d threads)\n",
        N, r.apparel_vertices, 100.0 * r.apparel_vertices / N, r.true_apparel_vertices,
        100.0 * r.true_apparel_vertices / N, r.faces, r.character.c_str(), r.bind_seconds, o.runtime_threads.back());
    if (r.handles > 0)
      std::printf(
          "runtime   %6d vertices: the apparel module moves %d handles (%.1f apparel vertices each), up to %d "
          "graph neighbours each\n",
          N, r.handles, double(r.apparel_vertices) / r.handles, r.handle_neighbors - 1);
    for (const RuntimeThreadFigures& t : r.per_thread) {
      std::printf(
          "runtime   %6d vertices, %d thread%s: per frame median %.2f ms, p95 %.2f ms (%.0f fps); "
          "split (medians) model %.2f [LBS %.2f, apparel network %.2f, refiner %.2f], penetration %.2f, output %.2f "
          "ms; "
          "penetration %.2f %% -> %.2f %% (inside tests carried over from the previous frame: %.0f %%); "
          "RSS %.0f MB, peak %.0f MB\n",
          N, t.threads, t.threads > 1 ? "s" : "", t.median_ms, t.p95_ms, 1e3 / t.median_ms, t.model_ms, t.lbs_ms,
          t.apparel_ms, t.refiner_ms, t.penetration_ms, t.output_ms, 100.0 * t.inside_before, 100.0 * t.inside_after,
          100.0 * t.carried_share, t.resident_mb, r.peak_resident_mb);
      if (std::isfinite(t.reference_apparel_ms))
        std::printf(
            "runtime   %6d vertices, %d thread%s: the global form's apparel network beside it %.2f ms: the "
            "apparel network is %.2fx it\n",
            N, t.threads, t.threads > 1 ? "s" : "", t.reference_apparel_ms, t.apparel_ms / t.reference_apparel_ms);
    }
    std::fflush(stdout);
  }
}

// Cloth retargeting (issue 13): two generated bodies dressed with one garment template (about 6k apparel
// vertices), both walking; registration of both sides, then the retargeting of a frame: steps 3-6, 3.1 and
// the edge relaxation alone, and with the push-out of 3.2 (inside tests and resolution), on one thread. The source
// apparel is the skinned apparel plus a swinging offset (a stand-in for a simulation: the cost does not depend on where
// the apparel is).
void bench_cloth(const BenchOptions& o) {
  set_thread_count(1);
  ApparelOptions dress;
  dress.vertex_fraction = 0.35f;
  dress.min_pieces = 2;
  dress.max_pieces = 3;
  const GeneratedBody body_a = generate_body(sample_body_params(uint64_t(7)), o.cloth_vertices);
  const DressedCharacter a = dress_character(body_a, 7, dress);
  dress.topology = a.topology;
  const GeneratedBody body_b = generate_body(sample_body_params(uint64_t(8)), o.cloth_vertices);
  const DressedCharacter b = dress_character(body_b, 7, dress);
  const ClothCharacter source{"bench:a", a.mesh, a.apparel_mask}, target{"bench:b", b.mesh, b.apparel_mask};
  const int repeats = std::max(3, o.repeats / 6);
  std::unique_ptr<ClothRetargeter> resolving;
  const double registration =
      median_seconds(repeats, [&] { resolving = std::make_unique<ClothRetargeter>(source, target); });
  ClothRetargetOptions core;  // steps 3-6, 3.1 and the relaxation: no winding-number queries
  core.resolve = false;
  core.measure = false;
  ClothRetargeter plain(source, target, core);
  const Motion walk_a = retarget_motion(walk_motion(o.repeats + 1), canonical_skeleton(), body_a.skeleton);
  const Motion walk_b = retarget_motion(walk_motion(o.repeats + 1), canonical_skeleton(), body_b.skeleton);
  std::vector<MatrixX3f> source_frames, target_frames;
  for (int t = 0; t < walk_a.num_frames(); ++t) {
    MatrixX3f Va, Vb;
    linear_blend_skinning(a.mesh.V, a.body_weights,
                          skinning_matrices(body_a.skeleton, forward_kinematics(body_a.skeleton, walk_a, t)), Va);
    linear_blend_skinning(b.mesh.V, b.body_weights,
                          skinning_matrices(body_b.skeleton, forward_kinematics(body_b.skeleton, walk_b, t)), Vb);
    for (const int32_t i : resolving->source_apparel())
      Va(i, 0) += 0.02f * std::sin(0.3f * float(t) + 0.01f * float(i));
    source_frames.push_back(std::move(Va));
    target_frames.push_back(std::move(Vb));
  }
  const int frames = int(source_frames.size());
  Penetration before, after;
  for (const bool resolve : {false, true}) {
    ClothRetargeter& r = resolve ? *resolving : plain;
    int t = 0;
    MatrixX3f V;
    const MedianTimes times = median_times(o.repeats, [&] {
      V = target_frames[size_t(t)];
      const ClothRetargetReport report = r.retarget(source_frames[size_t(t)], V);
      if (resolve) before.inside += report.before.inside, before.total += report.before.total;
      if (resolve) after.inside += report.after.inside, after.total += report.after.total;
      t = (t + 1) % frames;
    });
    std::printf(
        "cloth     %6d apparel vertices on %d + %d body vertices, 1 thread: retargeting %s median %.3f ms per "
        "frame (thread CPU time %.3f ms)\n",
        r.num_apparel(), body_a.mesh.num_vertices(), body_b.mesh.num_vertices(),
        resolve ? "with push-out (3.2)" : "steps 3-6, 3.1, relaxation", 1e3 * times.wall, 1e3 * times.cpu);
  }
  std::printf(
      "cloth     registration of both sides: median %.1f ms; penetration %.2f %% before, %.2f %% after push-out\n",
      1e3 * registration, 100.0 * before.share(), 100.0 * after.share());
}

// The segmenter on the characters of one split of a dataset, as built and remade (issue 17, item 4):
// per character and on average, the IoU of the predicted apparel mask (p > 0.5) and the share of
// vertices called apparel (beside the true share) on the character as built, on its bare body, on its
// open-parts version (open_parts_example: open, overlapping body parts with duplicated seams, holes
// under the clothes, a hair cap) and on that version's bare body. Bare bodies wear nothing: every
// vertex called apparel is an error.
void bench_segmenter(const BenchOptions& o) {
  AMT_CHECK(!o.data.empty(), "bench --suite segmenter: --data: expected dataset shards or folders, found none");
  const std::string dir = !o.model.empty() ? o.model : find_repository_folder("models/pretrained");
  const std::string checkpoint =
      !o.segmenter.empty() ? o.segmenter : (std::filesystem::path(dir) / kSegmenterCheckpoint).string();
  const ModelBundle bundle = load_segmenter_bundle(checkpoint);
  std::printf(
      "segmenter %s (inputs \"%s\"); %s characters of %zu dataset input%s; IoU of the mask p > 0.5; "
      "called = share of vertices called apparel (true share in brackets)\n",
      checkpoint.c_str(), bundle.segmenter->options.inputs.c_str(), o.split.c_str(), o.data.size(),
      o.data.size() > 1 ? "s" : "");
  struct Score {
    double iou = 0, called = 0, truth = 0;
  };
  const auto score = [&](const SegmenterExample& e) {
    const at::Tensor p = apparel_probabilities(bundle, e.mesh.V, e.mesh.F, e.skeleton.rest_joints).gt(0.5);
    const at::Tensor gt =
        at::from_blob(const_cast<uint8_t*>(e.apparel_mask.data()), {int64_t(e.apparel_mask.size())}, at::kByte)
            .to(at::kBool);
    const double inter = p.logical_and(gt).sum().item<double>(), uni = p.logical_or(gt).sum().item<double>();
    return Score{uni > 0 ? inter / uni : 1.0, p.to(at::kDouble).mean().item<double>(),
                 gt.to(at::kDouble).mean().item<double>()};
  };
  const char* kinds[4] = {"as built", "bare body", "open parts", "bare open parts"};
  Score sum[4];
  int count[4] = {0, 0, 0, 0};
  const auto print = [&](int k, const Score& s) {
    if (k == 1 || k == 3)
      std::printf("  %s called %.1f %%;", kinds[k], 100 * s.called);
    else
      std::printf("  %s IoU %.3f, called %.1f %% (%.1f %%);", kinds[k], s.iou, 100 * s.called, 100 * s.truth);
  };
  for (const std::string& shard : resolve_shards(o.data)) {
    const DatasetReader reader(shard);
    for (const std::string& name : reader.character_names()) {
      if (reader.character_summary(name).split != o.split) continue;
      const CharacterData data = reader.read_character(name);
      const SegmenterExample e{data.mesh, data.skeleton, data.body_weights, data.apparel_mask};
      // The bare body and the open-parts remake take the body from the builder's layout; an artist's model (a PMX or
      // VRM character's dataset) is scored as built only.
      const bool remade = builder_layout(e);
      std::vector<std::pair<int, Score>> scores{{0, score(e)}};
      std::string open_count = "-";
      if (remade) {
        const SegmenterExample open = open_parts_example(e);
        open_count = std::to_string(open.mesh.num_vertices());
        scores.push_back({1, score(bare_body_example(e))});
        scores.push_back({2, score(open)});
        scores.push_back({3, score(open_parts_example(e, true))});
      }
      std::printf("segmenter %-16s %6d vertices; open parts %6s:", name.c_str(), e.mesh.num_vertices(),
                  open_count.c_str());
      for (const auto& [k, s] : scores) {
        print(k, s);
        sum[k].iou += s.iou, sum[k].called += s.called, sum[k].truth += s.truth;
        ++count[k];
      }
      if (!remade) std::printf("  not laid out as the builder's characters: scored as built only;");
      std::printf("\n");
      std::fflush(stdout);
    }
  }
  AMT_CHECK(count[0] > 0, "bench --suite segmenter: no ", o.split, " characters in the given data");
  std::printf("segmenter mean over %d:", count[0]);
  for (int k = 0; k < 4; ++k) {
    if (count[k] == 0) continue;
    const double n = count[k];
    print(k, Score{sum[k].iou / n, sum[k].called / n, sum[k].truth / n});
    if (count[k] != count[0]) std::printf(" (over %d)", count[k]);
  }
  std::printf("\n");
}

}  // namespace

void add_bench_command(CLI::App& app) {
  auto options = std::make_shared<BenchOptions>();
  auto* bench = app.add_subcommand("bench", "Speed and memory figures (medians over repeats)");
  bench->add_option("--vertices", options->vertices, "Vertices of the generated stand-in character")
      ->check(CLI::Range(100, 5000000))
      ->capture_default_str();
  bench->add_option("--repeats", options->repeats, "Timed repeats per figure")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  bench
      ->add_option("--suite", options->suites,
                   "Suites to run: lbs, geodesic, runtime, cloth (retargeting), skinning (training steps), segmenter "
                   "(IoU and share called apparel on a dataset's characters, bare bodies and open-parts versions)")
      ->check(CLI::IsMember({"lbs", "geodesic", "runtime", "cloth", "skinning", "segmenter"}))
      ->capture_default_str();
  bench->add_option("--runtime-sizes", options->runtime_sizes, "Vertex counts of the runtime suite's characters")
      ->check(CLI::Range(2000, 200000))
      ->capture_default_str();
  bench->add_option("--runtime-threads", options->runtime_threads, "Thread counts of the runtime suite")
      ->check(CLI::Range(1, 1024))
      ->capture_default_str();
  bench->add_option("--cloth-vertices", options->cloth_vertices, "Vertices of each body of the cloth suite")
      ->check(CLI::Range(500, 200000))
      ->capture_default_str();
  bench->add_option("--model", options->model,
                    "Model folder of the runtime suite (fresh networks when absent). " +
                        repository_default_help("models/pretrained"));
  bench->add_flag("--open-parts", options->open_parts,
                  "Runtime suite: remake the characters as real models are built, a body of many open, overlapping "
                  "parts with holes under the clothes and a hair cap (data_tools/builder/open_parts.h)");
  bench->add_flag("--artist-style", options->artist_style,
                  "Runtime suite: remake the characters as artists build models (UV seams with coincident copies, hair "
                  "strips, double-sided and layered panels, open body parts; data_tools/builder/artist_style.h)");
  bench->add_flag("--segmenter-mask", options->segmenter_mask,
                  "Runtime suite: the apparel mask the segmenter predicts (as `amt animate` by default) instead of the "
                  "dressed character's");
  bench->add_flag("--refiner", options->refine,
                  "Runtime suite: also run the model's joint refiner, as amt animate --refiner (off by default, as "
                  "in amt animate)");
  bench
      ->add_option("--strain-limit", options->strain_limit,
                   "Runtime suite: the learned apparel's stretch limit, as amt animate --strain-limit (0: off)")
      ->check(CLI::Number & (CLI::IsMember({0.0f}) | CLI::Range(1.01f, 100.0f)))
      ->capture_default_str();
  bench->add_flag("--reference-apparel", options->reference_apparel,
                  "Runtime suite: also time the global apparel form's network (the form the local one replaced, at "
                  "its shipped widths) beside the model's, frame by frame, and print the ratio");
  bench->add_option("--data", options->data, "Segmenter suite: dataset shards (*.h5) or folders of them");
  bench->add_option("--segmenter", options->segmenter,
                    "Segmenter suite: the segmenter checkpoint scored (default: segmenter.ckpt of the model folder)");
  bench->add_option("--split", options->split, "Segmenter suite: the split whose characters are scored")
      ->check(CLI::IsMember({"train", "test"}))
      ->capture_default_str();
  add_threads_option(*bench);
  bench->callback([options] {
    const bool segmenter =
        std::find(options->suites.begin(), options->suites.end(), "segmenter") != options->suites.end();
    AMT_CHECK(!segmenter || !options->data.empty(),
              "bench --suite segmenter: --data: expected dataset shards or folders, found none");
    std::printf("amt bench: %d threads\n", omp_get_max_threads());
    for (const std::string& suite : options->suites) {
      if (suite == "lbs") bench_lbs(*options);
      if (suite == "geodesic") bench_geodesic(*options);
      if (suite == "runtime") bench_runtime(*options);
      if (suite == "cloth") bench_cloth(*options);
      if (suite == "skinning") bench_skinning(*options);
      if (suite == "segmenter") bench_segmenter(*options);
    }
    std::printf("peak resident memory: %.0f MB\n", peak_resident_mb());
  });
}

}  // namespace amt::app
