#include "data_tools/builder/dataset_builder.h"

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <ostream>
#include <random>
#include <sstream>

#include "data_tools/builder/apparel_simulation.h"
#include "data_tools/builder/body_generator.h"
#include "data_tools/builder/pmx_dataset.h"
#include "data_tools/builder/rig_response.h"
#include "data_tools/formats/atomic_file.h"
#include "data_tools/formats/dataset_file.h"
#include "data_tools/formats/input_file.h"
#include "data_tools/formats/temporary_registry.h"
#include "data_tools/geometry/error.h"
#include "data_tools/geometry/motion.h"

#ifdef _OPENMP
#include <omp.h>
#endif

namespace amt {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

constexpr const char* kManifestFormat = "amt-dataset-build";
constexpr int kManifestVersion = 1;
constexpr const char* kRecordFormat = "amt-character-record";
constexpr int kRecordVersion = 1;

// Streams of derive_seed(options.seed, .): one per use, so that changing one use leaves the others alone.
constexpr uint64_t kMotionStream = 0x6d6f74696f6eULL;      // procedural motions
constexpr uint64_t kCharacterSplitStream = 0x63737074ULL;  // held-out characters
constexpr uint64_t kClipSplitStream = 0x6b737074ULL;       // held-out clips
constexpr uint64_t kCharacterStream = 0x63686172ULL;       // per-character seeds
constexpr uint64_t kPmxSplitStream = 0x706d7873ULL;        // held-out PMX models

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

std::string duration_text(double seconds) {
  if (!std::isfinite(seconds) || seconds < 0) return "?";
  const long s = std::lround(seconds);
  char text[32];
  if (s >= 3600) {
    std::snprintf(text, sizeof(text), "%ldh%02ldm", s / 3600, (s / 60) % 60);
  } else {
    std::snprintf(text, sizeof(text), "%ldm%02lds", s / 60, s % 60);
  }
  return text;
}

// FNV-1a 64 of a file's bytes, as 16 hex digits (identifies the BVH and PMX files a dataset was built from).
// `what` says what the file should be, for messages ("a BVH motion").
std::string file_hash(const std::string& path, const char* what) {
  check_input_file(path, what);
  std::ifstream in(path, std::ios::binary);
  AMT_CHECK(in.good(), path, ": cannot read (expected ", what, ")");
  uint64_t h = 0xcbf29ce484222325ULL;
  char buffer[1 << 16];
  while (in) {
    in.read(buffer, sizeof(buffer));
    for (std::streamsize i = 0; i < in.gcount(); ++i) {
      h ^= static_cast<unsigned char>(buffer[i]);
      h *= 0x100000001b3ULL;
    }
  }
  char text[17];
  std::snprintf(text, sizeof(text), "%016llx", static_cast<unsigned long long>(h));
  return text;
}

// --- Manifest

json apparel_settings(const ApparelOptions& a) {
  json kinds = json::array();
  for (const ApparelKind kind : a.kinds) kinds.push_back(apparel_kind_name(kind));
  json settings = {{"min_pieces", a.min_pieces},
                   {"max_pieces", a.max_pieces},
                   {"kinds", kinds},
                   {"vertex_fraction", a.vertex_fraction},
                   {"max_bodies", a.max_bodies},
                   {"clearance", a.clearance},
                   {"capsule_margin", a.capsule_margin},
                   {"stiffness_scale", a.stiffness_scale},
                   {"damping_scale", a.damping_scale}};
  // Written only when set, so that the manifests of datasets built before the option still match.
  if (a.physics_variation > 0) settings["physics_variation"] = a.physics_variation;
  return settings;
}

// Everything that defines the dataset (not the shard, thread count, paths or progress of a run).
json make_manifest(const DatasetBuildOptions& o, const DatasetPlan& plan) {
  json manifest;
  manifest["format"] = kManifestFormat;
  manifest["version"] = kManifestVersion;
  manifest["settings"] = {{"seed", o.seed},
                          {"characters", o.characters},
                          {"procedural", o.procedural},
                          {"frames", o.frames},
                          {"vertices", o.vertices},
                          {"fps", o.fps},
                          {"blend_seconds", o.blend_seconds},
                          {"settle_seconds", o.settle_seconds},
                          {"physics_step", o.physics_step},
                          {"solver_iterations", o.solver_iterations},
                          {"test_character_every", o.test_character_every},
                          {"test_clip_every", o.test_clip_every},
                          {"clips_per_commit", o.clips_per_commit},
                          {"apparel", apparel_settings(o.apparel)}};
  if (!o.pmx.empty()) manifest["settings"]["pmx_metres_per_unit"] = o.pmx_metres_per_unit;
  if (!o.character_joint_map.empty()) {
    manifest["settings"]["character_joint_map"] = {{"file", fs::path(o.character_joint_map).filename().string()},
                                                   {"fnv1a64", file_hash(o.character_joint_map, "a joint map")}};
  }
  json bvh = json::array();
  if (!o.motions.empty()) {
    for (const std::string& path : list_bvh_files(o.motions)) {
      bvh.push_back({{"file", fs::path(path).filename().string()}, {"fnv1a64", file_hash(path, "a BVH motion")}});
    }
  }
  manifest["bvh_files"] = bvh;
  // The PMX models by name and checksum: a rerun with other files (or edited ones) is refused. Only written when
  // there are some, so that procedural builds keep their manifests.
  json pmx = json::array();
  for (const PlannedCharacter& c : plan.characters) {
    if (c.pmx.empty()) continue;
    pmx.push_back({{"character", c.name},
                   {"file", fs::path(c.pmx).filename().string()},
                   {"fnv1a64", file_hash(c.pmx, "a PMX model")}});
  }
  if (!pmx.empty()) manifest["pmx_files"] = pmx;
  json characters = json::array();
  for (const PlannedCharacter& c : plan.characters) {
    json entry = {{"name", c.name},
                  {"shard", fs::path(shard_path("", c.name)).filename().string()},
                  {"split", c.split},
                  {"body_seed", c.body_seed},
                  {"apparel_seed", c.apparel_seed}};
    if (!c.pmx.empty()) entry["pmx"] = fs::path(c.pmx).filename().string();
    characters.push_back(entry);
  }
  manifest["characters"] = characters;
  json clips = json::array();
  for (size_t k = 0; k < plan.clips.size(); ++k) {
    const MotionClip& clip = plan.clips[k];
    clips.push_back({{"name", clip.name},
                     {"source", clip.source},
                     {"first_frame", clip.first_frame},
                     {"frames", clip.motion.num_frames()},
                     {"held_out", static_cast<bool>(plan.clip_held_out[k])}});
  }
  manifest["clips"] = clips;
  return manifest;
}

// The first place where two JSON values differ, as "settings.seed: 1 here, 2 in the folder".
std::string first_difference(const json& here, const json& there, const std::string& path) {
  if (here.is_object() && there.is_object()) {
    for (auto it = here.begin(); it != here.end(); ++it) {
      if (!there.contains(it.key())) return path + it.key() + ": missing in the folder's manifest";
      const std::string d = first_difference(it.value(), there.at(it.key()), path + it.key() + ".");
      if (!d.empty()) return d;
    }
    for (auto it = there.begin(); it != there.end(); ++it) {
      if (!here.contains(it.key())) return path + it.key() + ": in the folder's manifest only";
    }
    return "";
  }
  if (here.is_array() && there.is_array() && here.size() == there.size()) {
    for (size_t i = 0; i < here.size(); ++i) {
      const std::string d = first_difference(here[i], there[i], path + std::to_string(i) + ".");
      if (!d.empty()) return d;
    }
    return "";
  }
  if (here == there) return "";
  std::string name = path.empty() ? "manifest" : path.substr(0, path.size() - 1);
  std::string a = here.dump(), b = there.dump();
  if (a.size() > 60) a = a.substr(0, 57) + "...";
  if (b.size() > 60) b = b.substr(0, 57) + "...";
  return name + ": " + a + " here, " + b + " in the folder";
}

std::string manifest_path(const std::string& dir) {
  return (fs::path(dir) / "manifest.json").string();
}

// Parses a manifest file and checks its format and version.
json read_manifest_file(const std::string& path) {
  check_input_file(path, "a dataset build manifest");
  std::ifstream in(path, std::ios::binary);
  AMT_CHECK(in.good(), path, ": cannot read (expected the manifest of an amt dataset build)");
  std::stringstream text;
  text << in.rdbuf();
  json manifest;
  try {
    manifest = json::parse(text.str());
  } catch (const json::exception& e) {
    fail(path, ": not valid JSON (", e.what(), "); expected the manifest of an amt dataset build");
  }
  const bool has_format = manifest.is_object() && manifest.contains("format");
  AMT_CHECK(has_format && manifest.value("format", "") == kManifestFormat, path, ": format: expected '",
            kManifestFormat, "', found ", has_format ? manifest["format"].dump() : std::string("none"));
  AMT_CHECK(manifest.value("version", -1) == kManifestVersion, path, ": version: expected ", kManifestVersion,
            ", found ", manifest.contains("version") ? manifest["version"].dump() : std::string("none"));
  return manifest;
}

// The first entry of `dir` that is neither manifest.json nor another shard process's temporary of it
// (manifest.json.PID.tmp), "" when there is none.
std::string foreign_entry(const std::string& dir) {
  std::error_code error;
  for (fs::directory_iterator it(dir, error), end; !error && it != end; it.increment(error)) {
    const std::string name = it->path().filename().string();
    const bool manifest_temporary =
        name.rfind("manifest.json.", 0) == 0 && name.size() > 18 && name.compare(name.size() - 4, 4, ".tmp") == 0;
    if (name != "manifest.json" && !manifest_temporary) return name;
  }
  return "";
}

// Writes DIR/manifest.json, or checks that the one there describes the same dataset. A folder without a
// manifest must be empty: a user's folder is refused, never filled (a shard process that started at the
// same time writes the manifest before anything else, so its files come with a manifest).
void check_or_write_manifest(const std::string& dir, const json& manifest) {
  const std::string path = manifest_path(dir);
  std::error_code error;
  if (!fs::exists(path, error)) {
    const std::string foreign = foreign_entry(dir);
    AMT_CHECK(foreign.empty() || fs::exists(path, error), dir, ": --out: expected an empty folder or one amt dataset ",
              "build wrote (manifest.json), found ", foreign, " without a manifest: name a new folder");
  }
  if (fs::exists(path, error)) {
    const json existing = read_manifest_file(path);
    // Settings first: they explain the other differences (seeds, clip lists).
    std::string difference;
    for (const char* key : {"settings", "bvh_files", "pmx_files", "clips", "characters"}) {
      const json none = std::string(key) == "pmx_files" ? json::array() : json();
      if (difference.empty())
        difference = first_difference(manifest.value(key, none), existing.value(key, none), std::string(key) + ".");
    }
    if (difference.empty()) return;
    // A manifest with nothing built under it (a run that failed before its first shard, for example on a PMX model
    // fixed since) is replaced; one with shards beside it describes them and stays.
    AMT_CHECK(foreign_entry(dir).empty(), dir, ": the folder holds a dataset built with other settings (", difference,
              "); use another --out or the same settings");
  }
  // Several shard processes may start at once: each writes its own temporary, the renames are atomic.
  const std::string temporary = path + "." + std::to_string(::getpid()) + ".tmp";
  register_temporary(temporary);
  {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    out << manifest.dump(2) << "\n";
    out.close();
    if (!out.good()) {
      discard_temporary(temporary);
      fail(temporary, ": write: expected the manifest written, found a write error (disk full or no writable folder?)");
    }
  }
  replace_with_temporary(temporary, path);
}

// --- Character record

json body_params_json(const BodyParams& p) {
  return {{"height", p.height},
          {"head_ratio", p.head_ratio},
          {"head_aspect", p.head_aspect},
          {"neck_ratio", p.neck_ratio},
          {"leg_ratio", p.leg_ratio},
          {"arm_ratio", p.arm_ratio},
          {"limb_thickness", p.limb_thickness},
          {"shoulder_width", p.shoulder_width},
          {"hip_width", p.hip_width},
          {"chest_radius", p.chest_radius},
          {"waist_radius", p.waist_radius},
          {"hip_radius", p.hip_radius},
          {"torso_depth", p.torso_depth},
          {"arm_angle_deg", p.arm_angle_deg}};
}

// The fields every build record has (dataset_quality.h reads them), procedural or PMX.
json record_fields(const PlannedCharacter& planned, json params, const TriMesh& mesh, int body_vertices, int body_faces,
                   const std::vector<uint8_t>& apparel_mask, int bones, int apparel_bodies, json pieces) {
  int apparel_vertices = 0;
  for (const uint8_t m : apparel_mask) apparel_vertices += m;
  return {{"format", kRecordFormat},
          {"version", kRecordVersion},
          {"name", planned.name},
          {"split", planned.split},
          {"body_seed", planned.body_seed},
          {"apparel_seed", planned.apparel_seed},
          {"params", std::move(params)},
          {"vertices", mesh.num_vertices()},
          {"faces", mesh.num_faces()},
          {"body_vertices", body_vertices},
          {"body_faces", body_faces},
          {"apparel_vertices", apparel_vertices},
          {"bones", bones},
          {"apparel_bodies", apparel_bodies},
          {"pieces", std::move(pieces)}};
}

json character_record(const PlannedCharacter& planned, const DressedCharacter& dressed) {
  json pieces = json::array();
  for (const ApparelPiece& piece : dressed.pieces) {
    pieces.push_back({{"kind", apparel_kind_name(piece.kind)},
                      {"connected_to_body", piece.connected_to_body},
                      {"attachment_joint", piece.attachment_joint},
                      {"attachment_joint_name", canonical_joint_names().at(piece.attachment_joint)},
                      {"chains", piece.chain_roots.size()},
                      {"chain_length", piece.chain_length},
                      {"first_vertex", piece.first_vertex},
                      {"end_vertex", piece.end_vertex}});
  }
  return record_fields(planned, body_params_json(dressed.body.params), dressed.mesh, dressed.body.mesh.num_vertices(),
                       dressed.body.mesh.num_faces(), dressed.apparel_mask, dressed.rig.num_bones(),
                       dressed.num_apparel_bodies(), std::move(pieces));
}

// The build record of a PMX character, in the procedural record's format (dataset_quality.h reads both): figures
// measured on the model, one piece per physics chain (pmx_dataset_character), the file and its repairs.
json pmx_character_record(const PlannedCharacter& planned, const PmxCharacter& pmx, const PmxDatasetCharacter& d) {
  const MatrixX3f& V = d.data.mesh.V;
  const MatrixX3f& J = d.data.skeleton.rest_joints;
  const double floor = V.col(1).minCoeff(), height = V.col(1).maxCoeff() - floor;
  const Eigen::Vector3f arm = J.row(kLeftElbow) - J.row(kLeftShoulder);
  const double pi = 3.14159265358979;
  const json params = {{"height", height},
                       {"head_ratio", height > 0 ? (V.col(1).maxCoeff() - J(kNeck, 1)) / height : 0.0},
                       {"leg_ratio", height > 0 ? (J(kLeftHip, 1) - floor) / height : 0.0},
                       {"arm_angle_deg", std::atan2(-arm.y(), std::hypot(arm.x(), arm.z())) * 180.0 / pi}};
  json pieces = json::array();
  for (const PmxApparelPiece& piece : d.pieces) {
    pieces.push_back({{"kind", "pmx_chain"},
                      {"connected_to_body", false},
                      {"attachment_joint", piece.attachment_joint},
                      {"attachment_joint_name", canonical_joint_names().at(piece.attachment_joint)},
                      {"root_bone", pmx.file_skeleton.names.at(piece.root_bone)},
                      {"chains", 1},
                      {"chain_length", piece.chain_length},
                      {"first_vertex", piece.first_vertex},
                      {"end_vertex", piece.end_vertex}});
  }
  json record = record_fields(planned, params, d.data.mesh, d.body_vertices, d.body_faces, d.data.apparel_mask,
                              pmx.num_bones(), pmx.simulated_bodies, std::move(pieces));
  record["pmx"] = {{"file", fs::path(planned.pmx).filename().string()},
                   {"model_name", pmx.model.header.name},
                   {"units", "simulated in PMX units, stored in metres"},
                   {"metres_per_unit", pmx.scale},
                   {"rigid_bodies", pmx.model.rigid_bodies.size()},
                   {"joints", pmx.model.joints.size()},
                   {"repairs", pmx.warnings}};
  return record;
}

// --- Simulation

// The frames of one simulated clip: T * J joint transforms and T * B rig skinning matrices, frame-major.
struct SimulatedClip {
  int frames = 0;
  Transforms joints;
  Transforms rig;
};

// Number of clips of `part` that form a committed prefix of the character's clip list.
int committed_clips(const std::string& part, const DatasetPlan& plan, int c, int per_commit) {
  const DatasetReader reader(part);
  const std::string& name = plan.characters[c].name;
  AMT_CHECK(reader.has_character(name), part, ": expected the part file of ", name, ", found no such character");
  const int M = static_cast<int>(plan.clips.size());
  int done = 0;
  while (done < M && reader.has_clip(plan.clip_name(c, done))) ++done;
  AMT_CHECK(static_cast<int>(reader.clip_names().size()) == done && (done % per_commit == 0 || done == M), part,
            ": expected the first clips of a batch boundary, found ", reader.clip_names().size(), " clips (", done,
            " in order)");
  return done;
}

}  // namespace

// === Options

std::vector<MotionClip> motion_library_of(const DatasetBuildOptions& o, uint64_t seed) {
  MotionLibraryOptions library;
  library.bvh_folder = o.motions;
  library.procedural = o.procedural;
  library.seed = seed;
  library.clip_frames = o.frames;
  library.fps = o.fps;
  return build_motion_library(library);
}

// The world settings of a generated character's clips (metres).
PhysicsSettings clip_physics_settings(const DatasetBuildOptions& o) {
  PhysicsSettings physics;
  physics.fixed_step = o.physics_step;
  physics.solver_iterations = o.solver_iterations;
  physics.max_substeps = std::max(physics.max_substeps, static_cast<int>(std::ceil(1.0 / o.fps / o.physics_step)));
  return physics;
}

Transforms simulate_clip(const DressedCharacter& dressed, const Transforms& joints, int frames,
                         const DatasetBuildOptions& o, std::unique_ptr<ApparelSimulator>& simulator) {
  const double dt = 1.0 / o.fps;
  if (!simulator) simulator = std::make_unique<ApparelSimulator>(dressed, clip_physics_settings(o));
  const int J = kCanonicalJointCount;
  auto pose = [&](int t) {
    return Transforms(joints.begin() + static_cast<ptrdiff_t>(t) * J,
                      joints.begin() + static_cast<ptrdiff_t>(t + 1) * J);
  };
  simulator->start(pose(0), o.settle_seconds);
  Transforms rig = simulator->skinning();
  for (int t = 1; t < frames; ++t) {
    const Transforms& step = simulator->step(pose(t), static_cast<float>(dt));
    rig.insert(rig.end(), step.begin(), step.end());
  }
  return rig;
}

ShardSpec parse_shard(const std::string& text) {
  ShardSpec shard;
  const size_t slash = text.find('/');
  bool ok = slash != std::string::npos && slash > 0 && slash + 1 < text.size() &&
            text.find_first_not_of("0123456789/") == std::string::npos && slash == text.rfind('/') && slash <= 6 &&
            text.size() - slash - 1 <= 6;
  if (ok) {
    shard.index = std::stoi(text.substr(0, slash));
    shard.count = std::stoi(text.substr(slash + 1));
    ok = shard.count >= 1 && shard.count <= 100000 && shard.index >= 0 && shard.index < shard.count;
  }
  AMT_CHECK(ok, "--shard: expected i/n with 0 <= i < n <= 100000 (e.g. 0/2), found '", text, "'");
  return shard;
}

void validate_build_options(const DatasetBuildOptions& o) {
  AMT_CHECK(!o.out.empty(), "dataset build: --out: expected an output folder, found none");
  const int least = o.pmx.empty() ? 1 : 0;
  AMT_CHECK(o.characters >= least && o.characters <= 100000, "dataset build: --characters: expected ", least,
            " to 100000", o.pmx.empty() ? " (or PMX models with --pmx)" : "", ", found ", o.characters);
  AMT_CHECK(std::isfinite(o.pmx_metres_per_unit) && o.pmx_metres_per_unit > 0,
            "dataset build: --pmx-metres-per-unit: expected a finite length > 0, found ", o.pmx_metres_per_unit);
  AMT_CHECK(o.character_joint_map.empty() || !o.pmx.empty(),
            "dataset build: --character-joint-map: maps the bones of --pmx models, but no --pmx model was given");
  AMT_CHECK(o.vertices >= kMinBodyVertices && o.vertices <= kMaxBodyVertices, "dataset build: --vertices: expected ",
            kMinBodyVertices, " to ", kMaxBodyVertices, " vertices per body, found ", o.vertices);
  AMT_CHECK(o.procedural >= 0 && o.procedural <= 100000, "dataset build: --procedural: expected 0 to 100000, found ",
            o.procedural);
  AMT_CHECK(o.frames >= 2 && o.frames <= 100000,
            "dataset build: --frames: expected 2 to 100000 frames per clip, found ", o.frames);
  AMT_CHECK(o.motions.empty() ? o.procedural > 0 : true,
            "dataset build: expected motions: a --motions folder or --procedural > 0, found neither");
  AMT_CHECK(std::isfinite(o.fps) && o.fps > 0 && o.fps <= 1000, "dataset build: fps: expected (0, 1000], found ",
            o.fps);
  AMT_CHECK(std::isfinite(o.blend_seconds) && o.blend_seconds >= 0 && o.blend_seconds <= 60,
            "dataset build: blend seconds: expected [0, 60], found ", o.blend_seconds);
  AMT_CHECK(std::isfinite(o.settle_seconds) && o.settle_seconds >= 0 && o.settle_seconds <= 60,
            "dataset build: settle seconds: expected [0, 60], found ", o.settle_seconds);
  AMT_CHECK(std::isfinite(o.physics_step) && o.physics_step >= 1.0f / 2000.0f && o.physics_step <= 1.0f / 30.0f,
            "dataset build: physics step: expected [1/2000, 1/30] s, found ", o.physics_step);
  AMT_CHECK(o.solver_iterations >= 1 && o.solver_iterations <= 200,
            "dataset build: solver iterations: expected 1 to 200, found ", o.solver_iterations);
  AMT_CHECK(o.test_character_every >= 2 && o.test_clip_every >= 2,
            "dataset build: held-out ratios: expected one in 2 or more characters and clips, found one in ",
            o.test_character_every, " and one in ", o.test_clip_every);
  AMT_CHECK(o.clips_per_commit >= 1, "dataset build: clips per commit: expected >= 1, found ", o.clips_per_commit);
  AMT_CHECK(o.shard.count >= 1 && o.shard.index >= 0 && o.shard.index < o.shard.count,
            "dataset build: --shard: expected i/n with 0 <= i < n, found ", o.shard.index, "/", o.shard.count);
  validate_apparel_options(o.apparel);
}

// === Plan

std::vector<bool> held_out_set(int n, int every, uint64_t seed) {
  std::vector<bool> held(std::max(n, 0), false);
  if (n < 2) return held;
  const int count = std::max(1, static_cast<int>(std::lround(static_cast<double>(n) / every)));
  std::vector<int> order(n);
  for (int i = 0; i < n; ++i) order[i] = i;
  std::mt19937_64 rng(seed);
  for (int i = n - 1; i > 0; --i) {  // Fisher-Yates with the engine's raw output (platform independent)
    const int j = static_cast<int>(rng() % static_cast<uint64_t>(i + 1));
    std::swap(order[i], order[j]);
  }
  for (int i = 0; i < count; ++i) held[order[i]] = true;
  return held;
}

std::string DatasetPlan::clip_split(int c, int k) const {
  return characters.at(c).split == "test" || clip_held_out.at(k) ? "test" : "train";
}

std::string DatasetPlan::clip_name(int c, int k) const {
  return characters.at(c).name + "__" + clips.at(k).name;
}

DatasetPlan plan_dataset(const DatasetBuildOptions& options, std::vector<MotionClip> clips) {
  DatasetPlan plan;
  const std::vector<bool> test_characters =
      held_out_set(options.characters, options.test_character_every, derive_seed(options.seed, kCharacterSplitStream));
  for (int c = 0; c < options.characters; ++c) {
    char name[32];
    std::snprintf(name, sizeof(name), "character-%04d", c);
    const uint64_t base = derive_seed(derive_seed(options.seed, kCharacterStream), static_cast<uint64_t>(c));
    plan.characters.push_back(
        {name, derive_seed(base, 0), derive_seed(base, 1), test_characters[c] ? "test" : "train", std::string()});
  }
  const std::vector<std::string> models = list_pmx_files(options.pmx);
  const std::vector<bool> test_models = held_out_set(static_cast<int>(models.size()), options.test_character_every,
                                                     derive_seed(options.seed, kPmxSplitStream));
  for (size_t m = 0; m < models.size(); ++m) {
    char name[32];
    std::snprintf(name, sizeof(name), "pmx-%04d", static_cast<int>(m));
    plan.characters.push_back({name, 0, 0, test_models[m] ? "test" : "train", models[m]});
  }
  plan.clip_held_out = held_out_set(static_cast<int>(clips.size()), options.test_clip_every,
                                    derive_seed(options.seed, kClipSplitStream));
  plan.clips = std::move(clips);
  return plan;
}

std::vector<std::string> list_pmx_files(const std::vector<std::string>& paths) {
  std::vector<std::string> files;
  const auto is_pmx = [](const fs::path& p) {
    std::string e = p.extension().string();
    std::transform(e.begin(), e.end(), e.begin(), [](unsigned char ch) { return static_cast<char>(std::tolower(ch)); });
    return e == ".pmx";
  };
  for (const std::string& path : paths) {
    std::error_code error;
    AMT_CHECK(fs::exists(path, error), path, ": --pmx: expected a PMX file or a folder of them, found nothing there");
    if (fs::is_directory(path, error)) {
      std::vector<std::string> found;
      for (fs::directory_iterator it(path, error), end; !error && it != end; it.increment(error)) {
        if (it->is_regular_file() && is_pmx(it->path())) found.push_back(it->path().string());
      }
      AMT_CHECK(!found.empty(), path, ": --pmx: expected a folder with *.pmx files, found none");
      std::sort(found.begin(), found.end());
      files.insert(files.end(), found.begin(), found.end());
    } else {
      AMT_CHECK(is_pmx(path), path, ": --pmx: expected a .pmx file, found extension '",
                fs::path(path).extension().string(), "'");
      files.push_back(path);
    }
  }
  return files;
}

BuildManifest read_build_manifest(const std::string& dir) {
  const std::string path = manifest_path(dir);
  const json manifest = read_manifest_file(path);
  const auto array = [&](const char* key) -> const json& {
    AMT_CHECK(manifest.contains(key) && manifest[key].is_array(), path, ": ", key, ": expected an array");
    return manifest[key];
  };
  // Entry `i` of array `key` is an object whose `field` satisfies `ok`.
  const auto check = [&](const char* key, size_t i, const json& entry, const char* field, auto ok,
                         const char* expected) {
    const bool has = entry.is_object() && entry.contains(field);
    AMT_CHECK(has && ok(entry[field]), path, ": ", key, ".", i, ".", field, ": expected ", expected, ", found ",
              has ? entry[field].dump() : "none");
  };
  const auto is_seed = [](const json& v) { return v.is_number_unsigned(); };
  BuildManifest result;
  const json& characters = array("characters");
  for (size_t i = 0; i < characters.size(); ++i) {
    const json& c = characters[i];
    // The name becomes a file name in DIR: it must not lead out of the folder.
    check(
        "characters", i, c, "name",
        [](const json& v) {
          return v.is_string() && !v.get<std::string>().empty() &&
                 v.get<std::string>().find('/') == std::string::npos && v.get<std::string>() != "." &&
                 v.get<std::string>() != "..";
        },
        "a character name without '/'");
    check(
        "characters", i, c, "split", [](const json& v) { return v == "train" || v == "test"; }, "train or test");
    check("characters", i, c, "body_seed", is_seed, "a seed");
    check("characters", i, c, "apparel_seed", is_seed, "a seed");
    result.characters.push_back({c["name"].get<std::string>(), c["body_seed"].get<uint64_t>(),
                                 c["apparel_seed"].get<uint64_t>(), c["split"].get<std::string>(), std::string()});
  }
  const json& clips = array("clips");
  for (size_t k = 0; k < clips.size(); ++k) {
    check(
        "clips", k, clips[k], "frames", [](const json& v) { return v.is_number_unsigned(); }, "a frame count");
    result.frames_per_character += clips[k]["frames"].get<int64_t>();
  }
  result.clips_per_character = static_cast<int>(clips.size());
  return result;
}

std::string shard_path(const std::string& dir, const std::string& character) {
  return (fs::path(dir) / (character + ".h5")).string();
}
std::string record_path(const std::string& dir, const std::string& character) {
  return (fs::path(dir) / (character + ".json")).string();
}
std::string part_path(const std::string& dir, const std::string& character) {
  return (fs::path(dir) / (character + ".part")).string();
}

// === Build

DatasetBuildReport build_dataset(const DatasetBuildOptions& o) {
  const Clock::time_point start = Clock::now();
  validate_build_options(o);
  DatasetBuildReport report;
  // Read before anything is written, so that a bad map is refused at once.
  std::optional<JointMapFile> joint_map;
  if (!o.character_joint_map.empty()) joint_map = read_joint_map(o.character_joint_map);

  const DatasetPlan plan = plan_dataset(o, motion_library_of(o, derive_seed(o.seed, kMotionStream)));
  const json manifest = make_manifest(o, plan);
  // This process's PMX models are read and mapped before the folder is touched: a model the name table cannot map
  // is refused without leaving a manifest behind, so the rerun with --character-joint-map starts clean.
  for (int c = o.shard.index; c < static_cast<int>(plan.characters.size()); c += o.shard.count) {
    if (!plan.characters[c].pmx.empty()) load_pmx_character(plan.characters[c].pmx, joint_map, o.pmx_metres_per_unit);
  }

  std::error_code error;
  fs::create_directories(o.out, error);
  AMT_CHECK(!error && fs::is_directory(o.out), o.out,
            ": --out: expected a folder that can be created, found error: ", error.message());
  check_or_write_manifest(o.out, manifest);

  const int C = static_cast<int>(plan.characters.size()), M = static_cast<int>(plan.clips.size());
  int64_t frames_per_character = 0;
  for (const MotionClip& clip : plan.clips) frames_per_character += clip.motion.num_frames();
  std::vector<int> mine;
  for (int c = o.shard.index; c < C; c += o.shard.count) mine.push_back(c);
  report.characters_total = static_cast<int>(mine.size());
  report.clips_total = report.characters_total * M;
  // A finished shard is done only if it reads back whole (every checksum and compressed stream): a
  // damaged one is rebuilt, and replaced by the rename that finishes it.
  int64_t frames_to_do = 0;
  std::map<int, std::string> damaged;  // character -> what verification found
  for (const int c : mine) {
    const std::string shard = shard_path(o.out, plan.characters[c].name);
    if (fs::exists(shard, error)) {
      try {
        DatasetReader(shard).verify();
        continue;
      } catch (const Error& e) {
        damaged[c] = e.what();
        report.damaged.push_back(e.what());
      }
    }
    frames_to_do += frames_per_character;
  }
  if (o.progress) {
    *o.progress << "build: " << o.out << ": shard " << o.shard.index << "/" << o.shard.count << ": "
                << report.characters_total << " of " << C << " characters x " << M << " clips (" << frames_per_character
                << " frames each)\n";
  }

  int clips_this_run = 0;
  int64_t apparel_bodies = 0;
  int characters_done = 0;
  for (const int c : mine) {
    const PlannedCharacter& planned = plan.characters[c];
    const std::string shard = shard_path(o.out, planned.name), part = part_path(o.out, planned.name);
    if (damaged.count(c)) {
      if (o.progress) *o.progress << "build: " << damaged[c] << ": rebuilding " << planned.name << "\n";
    } else if (fs::exists(shard, error)) {
      ++report.characters_skipped;
      report.clips_skipped += M;
      ++characters_done;
      continue;
    }
    int done = 0;
    if (fs::exists(part, error)) {
      // The part file is the builder's own: one that cannot be resumed (cut short, a dataset failing its checksum,
      // clips out of order) is rebuilt from the character's first clip, never trusted and never left to block.
      try {
        DatasetReader(part).verify();
        done = committed_clips(part, plan, c, o.clips_per_commit);
      } catch (const Error& e) {
        if (o.progress)
          *o.progress << "build: " << e.what() << ": rebuilding " << planned.name << " from its first clip\n";
        report.damaged.push_back(e.what());
        fs::remove(part, error);
        AMT_CHECK(!error, part, ": expected to remove the damaged part file, found error: ", error.message());
        done = 0;
      }
    }
    report.clips_skipped += done;
    for (int k = 0; k < done; ++k) frames_to_do -= plan.clips[k].motion.num_frames();

    // A procedural character (generated and dressed) or a PMX model (read and repaired; its repairs are printed).
    Clock::time_point t0 = Clock::now();
    std::optional<GeneratedBody> body;
    std::optional<DressedCharacter> dressed;
    std::optional<PmxCharacter> pmx;
    if (planned.pmx.empty()) {
      body.emplace(generate_body(sample_body_params(planned.body_seed), o.vertices));
      report.body_seconds += seconds_since(t0);
      t0 = Clock::now();
      dressed.emplace(dress_character(*body, planned.apparel_seed, o.apparel));
      report.dress_seconds += seconds_since(t0);
      apparel_bodies += dressed->num_apparel_bodies();
    } else {
      pmx.emplace(load_pmx_character(planned.pmx, joint_map, o.pmx_metres_per_unit));
      report.body_seconds += seconds_since(t0);
      apparel_bodies += pmx->simulated_bodies;
      if (o.progress) {
        *o.progress << "build: " << planned.name << " <- " << planned.pmx << ": " << pmx->mesh.num_vertices()
                    << " vertices, " << pmx->num_bones() << " bones, " << pmx->model.rigid_bodies.size()
                    << " rigid bodies (" << pmx->simulated_bodies << " simulated), " << pmx->model.joints.size()
                    << " joints\n";
        for (const std::string& warning : pmx->warnings) *o.progress << "build: warning: " << warning << "\n";
      }
    }
    const Skeleton& skeleton = pmx ? pmx->skeleton() : body->skeleton;
    PmxSimulationOptions pmx_options;
    pmx_options.fps = o.fps;
    pmx_options.physics_step = o.physics_step;
    pmx_options.solver_iterations = o.solver_iterations;
    pmx_options.settle_seconds = o.settle_seconds;

    int threads = 1;
#ifdef _OPENMP
    threads = std::max(1, omp_get_max_threads());
#endif
    std::vector<std::unique_ptr<ApparelSimulator>> simulators(threads);
    std::vector<std::unique_ptr<PmxRigSimulator>> pmx_simulators(threads);
    for (int batch = done; batch < M; batch += o.clips_per_commit) {
      const int end = std::min(M, batch + o.clips_per_commit);
      // Motions on the character (sequential: cheap), then the batch's clips in parallel.
      t0 = Clock::now();
      std::vector<SimulatedClip> simulated(end - batch);
      for (int k = batch; k < end; ++k) {
        const Motion motion = clip_on_character(plan.clips[k], skeleton, o.blend_seconds);
        simulated[k - batch].frames = motion.num_frames();
        simulated[k - batch].joints = forward_kinematics(skeleton, motion);
      }
      report.motion_seconds += seconds_since(t0);
      t0 = Clock::now();
      std::exception_ptr failure;
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
      for (int i = 0; i < end - batch; ++i) {
        try {
          int thread = 0;
#ifdef _OPENMP
          thread = omp_get_thread_num();
#endif
          SimulatedClip& clip = simulated[i];
          clip.rig = pmx ? simulate_pmx_clip(*pmx, clip.joints, clip.frames, pmx_options, pmx_simulators[thread])
                         : simulate_clip(*dressed, clip.joints, clip.frames, o, simulators[thread]);
        } catch (...) {
#pragma omp critical(amt_dataset_build_failure)
          if (!failure) failure = std::current_exception();
        }
      }
      if (failure) std::rethrow_exception(failure);
      report.simulate_seconds += seconds_since(t0);

      // Write the batch in clip order and commit it.
      t0 = Clock::now();
      std::optional<DatasetWriter> writer;
      if (fs::exists(part, error)) {
        writer.emplace(DatasetWriter::append(part));
      } else {
        writer.emplace(part, o.fps, canonical_joint_names());
        CharacterData data = pmx ? pmx_dataset_character(*pmx, planned.name, planned.split).data
                                 : dressed->character_data(planned.name, planned.split);
        // How lively the character's apparel physics is, on the same world settings as its clips.
        data.rig->response =
            pmx ? rig_response(pmx->physics, pmx_simulation_settings(pmx_options, planned.name), pmx->scale)
                : rig_response(dressed->rig, clip_physics_settings(o), 1.0f);
        writer->add_character(data);
      }
      const int B = pmx ? pmx->num_bones() : dressed->rig.num_bones(), J = kCanonicalJointCount;
      for (int k = batch; k < end; ++k) {
        const SimulatedClip& clip = simulated[k - batch];
        ClipInfo info;
        info.name = plan.clip_name(c, k);
        info.character = planned.name;
        info.motion = plan.clips[k].name;
        info.split = plan.clip_split(c, k);
        info.fps = o.fps;
        info.ground_truth = GroundTruth::kRig;
        writer->begin_clip(info);
        for (int t = 0; t < clip.frames; ++t) {
          const Transforms joints(clip.joints.begin() + static_cast<ptrdiff_t>(t) * J,
                                  clip.joints.begin() + static_cast<ptrdiff_t>(t + 1) * J);
          const Transforms rig(clip.rig.begin() + static_cast<ptrdiff_t>(t) * B,
                               clip.rig.begin() + static_cast<ptrdiff_t>(t + 1) * B);
          writer->append_frame(joints, rig);
        }
        writer->end_clip();
        report.frames += clip.frames;
        frames_to_do -= clip.frames;
        ++clips_this_run;
        if (o.stop_after_clips >= 0 && clips_this_run >= o.stop_after_clips) {
          // As if killed here: the writer's temporary goes, the last commit stays.
          report.interrupted = true;
          report.seconds = seconds_since(start);
          report.mean_apparel_bodies = static_cast<double>(apparel_bodies) / std::max(1, report.characters_built + 1);
          return report;
        }
      }
      writer->commit();
      report.clips_built += end - batch;
      report.write_seconds += seconds_since(t0);

      if (o.progress) {
        const double elapsed = seconds_since(start);
        const double rate = report.frames / std::max(elapsed, 1e-9);
        *o.progress << "build: character " << characters_done + 1 << "/" << report.characters_total << " ("
                    << planned.name << "), clips " << report.clips_built + report.clips_skipped << "/"
                    << report.clips_total << ", " << std::fixed << std::setprecision(1) << rate << " frames/s, ETA "
                    << duration_text(frames_to_do / std::max(rate, 1e-9)) << "\n"
                    << std::defaultfloat;
      }
    }

    // Finish the character: its record, then the shard appears under its final name.
    t0 = Clock::now();
    const json record =
        pmx ? pmx_character_record(planned, *pmx, pmx_dataset_character(*pmx, planned.name, planned.split))
            : character_record(planned, *dressed);
    write_file_atomically(record_path(o.out, planned.name), record.dump(2) + "\n");
    std::error_code rename_error;
    fs::rename(part, shard, rename_error);
    AMT_CHECK(!rename_error, shard, ": expected to rename ", part, " onto it, found error: ", rename_error.message());
    report.write_seconds += seconds_since(t0);
    ++report.characters_built;
    ++characters_done;
  }
  report.seconds = seconds_since(start);
  report.mean_apparel_bodies =
      report.characters_built > 0 ? static_cast<double>(apparel_bodies) / report.characters_built : 0.0;
  return report;
}

void print_build_report(const DatasetBuildReport& r, std::ostream& out) {
  const double stages = r.body_seconds + r.dress_seconds + r.motion_seconds + r.simulate_seconds + r.write_seconds;
  auto share = [&](double s) {
    std::ostringstream text;
    text << std::fixed << std::setprecision(1) << s << " s (" << std::setprecision(0)
         << (stages > 0 ? 100.0 * s / stages : 0.0) << " %)";
    return text.str();
  };
  out << "built " << r.characters_built << " characters (" << r.characters_skipped << " already done), "
      << r.clips_built << " clips (" << r.clips_skipped << " already done), " << r.frames << " frames in " << std::fixed
      << std::setprecision(1) << r.seconds << " s: " << (r.seconds > 0 ? r.frames / r.seconds : 0.0) << " frames/s"
      << (r.interrupted ? " (stopped early)" : "") << "\n"
      << "stages: body generation " << share(r.body_seconds) << ", dressing " << share(r.dress_seconds) << ", motions "
      << share(r.motion_seconds) << ", simulation " << share(r.simulate_seconds) << ", writing "
      << share(r.write_seconds) << "; " << std::setprecision(1) << r.mean_apparel_bodies
      << " apparel bodies per character\n"
      << std::defaultfloat;
}

}  // namespace amt
