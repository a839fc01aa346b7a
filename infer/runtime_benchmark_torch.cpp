#include "infer/runtime_benchmark_torch.h"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>

#include "data_tools/builder/apparel.h"
#include "data_tools/builder/artist_style.h"
#include "data_tools/builder/body_generator.h"
#include "data_tools/builder/open_parts.h"
#include "data_tools/geometry/error.h"
#include "data_tools/geometry/procedural_motion.h"
#include "data_tools/geometry/retarget.h"
#include "data_tools/geometry/threads.h"
#include "infer/bind_cache_torch.h"
#include "infer/glb_stream_writer.h"
#include "infer/runtime_torch.h"
#include "models/edge_conv.h"

namespace amt {
namespace {

// Open-parts characters: the body's share of the requested size before the parts' copies and the cap,
// and the apparel fraction, chosen so that a requested size of about 14.5k gives about that many
// vertices with 10-30 % apparel.
constexpr float kOpenPartsBodyShare = 0.66f;
constexpr float kOpenPartsApparelFraction = 0.2f;

int count_ones(const std::vector<uint8_t>& mask) {
  int n = 0;
  for (uint8_t m : mask) n += m ? 1 : 0;
  return n;
}

}  // namespace

std::pair<double, double> median_p95(std::vector<double>& v) {
  if (v.empty()) return {std::nan(""), std::nan("")};
  std::sort(v.begin(), v.end());
  const size_t p95 = std::min(v.size() - 1, size_t(std::ceil(0.95 * double(v.size()))) - 1);
  return {v[v.size() / 2], v[p95]};
}

double peak_resident_mb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss / 1024.0;
}

double resident_mb() {
  std::ifstream status("/proc/self/status");
  std::string key;
  while (status >> key) {
    if (key == "VmRSS:") {
      double kb = 0;
      status >> kb;
      return kb / 1024.0;
    }
  }
  return 0.0;
}

namespace {

// `bundle` with its apparel module replaced by the global form as it was shipped before the local form replaced
// it (models/pretrained/apparel.ckpt of that time: motion MLP 64 -> code 16, EdgeConv 32/32/64, decoder 32),
// freshly initialised: the reference of the local form's cost.
ModelBundle with_reference_apparel(const ModelBundle& bundle) {
  ApparelDisplacementOptions o;
  o.num_joints = bundle.num_joints();
  o.motion_widths = {64};
  o.motion_code = 16;
  o.edge_widths = {32, 32, 64};
  o.decoder_widths = {32};
  ModelBundle reference = bundle;
  reference.apparel = ApparelDisplacementNet(o);
  reference.apparel->eval();
  reference.apparel_dynamics = ApparelDynamicsNet(nullptr);
  reference.apparel_dynamics_own_weights = ApparelDynamicsNet(nullptr);
  return reference;
}

}  // namespace

RuntimeFigures measure_runtime(const ModelBundle& bundle, const RuntimeBenchmarkOptions& o, const std::string& label) {
  AMT_CHECK(!o.threads.empty() && o.repeats >= 1, "runtime benchmark: expected thread counts and at least one repeat");
  RuntimeFigures r;
  r.label = label;
  r.repeats = o.repeats;
  r.mask = o.segmenter_mask ? "the segmenter" : "the dressed character";
  const int caller_threads = thread_count();  // restored at the end
  set_thread_count(o.threads.back());
  ApparelOptions dress;
  dress.vertex_fraction = o.open_parts ? kOpenPartsApparelFraction : 0.3f;
  dress.min_pieces = 2;
  dress.max_pieces = 3;
  const float body_share = o.open_parts ? kOpenPartsBodyShare : 0.7f;
  // An artist-style remake has about 3 times the vertices of the character it remakes (copies, reverse sides,
  // layers) before its subdivision to `vertices`.
  const float remake_growth = o.artist_style ? 3.2f : 1.0f;
  const GeneratedBody body = generate_body(sample_body_params(uint64_t(7)),
                                           std::max(kMinBodyVertices, int(o.vertices * body_share / remake_growth)));
  // Open parts: the items of a typical real model (twin tails, a skirt on physics chains, a tie).
  const DressedCharacter dressed =
      o.open_parts ? dress_character_with(
                         body, {ApparelKind::kPleatedSkirt, ApparelKind::kTwinTails, ApparelKind::kRibbons}, 7, dress)
                   : dress_character(body, 7, dress);
  TriMesh mesh = dressed.mesh;
  std::vector<uint8_t> mask = dressed.apparel_mask;
  r.character = "a dressed procedural body";
  if (o.open_parts) {
    OpenPartsCharacter open = open_parts_character(dressed);
    r.character = "a dressed procedural body remade of " + std::to_string(open.num_parts) + " open body parts (" +
                  std::to_string(open.dropped_faces) + " body faces dropped under the clothes, a hair cap)";
    mesh = std::move(open.mesh);
    mask = std::move(open.apparel_mask);
  }
  if (o.artist_style) {
    CharacterData source;
    source.name = "bench";
    source.mesh = dressed.mesh;
    source.skeleton = body.skeleton;
    source.apparel_mask = dressed.apparel_mask;
    source.body_weights = dressed.body_weights;
    ArtistStyleOptions artist;
    artist.target_vertices = o.vertices;
    ArtistStyleCharacter remade = artist_style_character(source, artist);
    const MeshConstruction parts = mesh_construction(remade.character.mesh.V, remade.character.mesh.F);
    r.character = "a dressed procedural body remade artist-style (" + std::to_string(parts.parts) + " parts, " +
                  std::to_string(parts.welded_parts) + " once seams are welded)";
    mesh = std::move(remade.character.mesh);
    mask = std::move(remade.character.apparel_mask);
  }
  r.vertices = mesh.num_vertices();
  r.faces = mesh.num_faces();
  r.true_apparel_vertices = count_ones(mask);
  const BindResult bind =
      bind_cached(bundle, mesh, body.skeleton.rest_joints, o.segmenter_mask ? std::vector<uint8_t>{} : mask, "");
  r.bind_seconds = bind.seconds;
  const at::Tensor bound_mask = bind.bound.apparel_mask.to(at::kByte).contiguous();
  const std::vector<uint8_t> bound_mask_values(bound_mask.data_ptr<uint8_t>(),
                                               bound_mask.data_ptr<uint8_t>() + bound_mask.numel());
  r.apparel_vertices = count_ones(bound_mask_values);
  if (bind.bound.handle_rows.defined()) {
    r.handles = int(bind.bound.handle_rows.size(0));
    r.handle_neighbors = int(neighbor_table(r.handles, bind.bound.handle_edges).size(1));
  }
  // The reference runs on the mask the model's bind chose, so that both networks see the same apparel.
  const bool reference = o.reference_apparel && bundle.local_apparel();
  const ModelBundle reference_bundle = reference ? with_reference_apparel(bundle) : ModelBundle{};
  BindResult reference_bind;
  if (reference) {
    reference_bind = bind_cached(reference_bundle, mesh, body.skeleton.rest_joints, bound_mask_values, "");
  }
  const Motion walk = retarget_motion(walk_motion(o.repeats + 1), canonical_skeleton(), body.skeleton);
  const std::filesystem::path scratch =
      std::filesystem::path(o.scratch_dir.empty() ? std::filesystem::temp_directory_path().string() : o.scratch_dir) /
      ("amt_runtime_" + std::to_string(::getpid()) + ".glb");
  for (const int threads : o.threads) {
    set_thread_count(threads);
    RuntimeSession session(bundle, bind.bound, mesh.F, /*resolve=*/true, {}, o.refine, o.strain_limit);
    const Transforms first = forward_kinematics(body.skeleton, walk, 0);
    const at::Tensor lead = motion_lead_in(transforms_tensor(first), session.bound().joints, kDefaultLeadInFrames);
    for (int64_t k = 0; k < lead.size(0); ++k) session.advance(lead[k]);
    std::unique_ptr<RuntimeSession> reference_session;
    if (reference) {
      reference_session =
          std::make_unique<RuntimeSession>(reference_bundle, reference_bind.bound, mesh.F, /*resolve=*/false);
      for (int64_t k = 0; k < lead.size(0); ++k) reference_session->advance(lead[k]);
    }
    std::vector<double> totals, model, pen, out, lbs, app, ref, reference_app;
    Penetration before, after;
    int64_t carried = 0;
    {
      GlbStreamWriter writer(scratch.string(), mesh.F, r.vertices, 30.0f);
      MatrixX3f V;
      PenetrationReport report;
      for (int t = 0; t < o.repeats; ++t) {
        const Transforms T = forward_kinematics(body.skeleton, walk, t);
        FrameTimes times = session.step(T, V, &report);
        const auto w = std::chrono::steady_clock::now();
        writer.append(V);
        times.output = std::chrono::duration<double>(std::chrono::steady_clock::now() - w).count();
        totals.push_back(times.total()), model.push_back(times.model), pen.push_back(times.penetration),
            out.push_back(times.output);
        before.inside += report.before.inside, before.total += report.before.total;
        after.inside += report.after.inside, after.total += report.after.total;
        carried += report.carried;
        // Stage split, as the pipeline stepper timed it within this very frame.
        lbs.push_back(times.stages.lbs), app.push_back(times.stages.apparel), ref.push_back(times.stages.refiner);
        if (reference_session) {
          MatrixX3f V_reference;
          reference_app.push_back(reference_session->step(T, V_reference).stages.apparel);
        }
      }
    }
    std::error_code ignored;
    std::filesystem::remove(scratch, ignored);
    RuntimeThreadFigures f;
    f.threads = threads;
    std::tie(f.median_ms, f.p95_ms) = median_p95(totals);
    f.median_ms *= 1e3, f.p95_ms *= 1e3;
    f.model_ms = 1e3 * median_p95(model).first;
    f.lbs_ms = 1e3 * median_p95(lbs).first, f.apparel_ms = 1e3 * median_p95(app).first;
    f.refiner_ms = 1e3 * median_p95(ref).first, f.penetration_ms = 1e3 * median_p95(pen).first;
    f.output_ms = 1e3 * median_p95(out).first;
    f.inside_before = before.share(), f.inside_after = after.share();
    f.carried_share = before.total > 0 ? double(carried) / double(before.total) : 0.0;
    f.resident_mb = resident_mb();
    if (!reference_app.empty()) f.reference_apparel_ms = 1e3 * median_p95(reference_app).first;
    r.per_thread.push_back(f);
  }
  r.peak_resident_mb = peak_resident_mb();
  set_thread_count(caller_threads);
  return r;
}

}  // namespace amt
