#include "infer/character_input.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "data_tools/builder/apparel.h"
#include "data_tools/builder/body_generator.h"
#include "data_tools/builder/pmx_dataset.h"
#include "data_tools/builder/pmx_physics.h"
#include "data_tools/builder/rig_response.h"
#include "data_tools/formats/dataset_file.h"
#include "data_tools/formats/gltf_import.h"
#include "data_tools/formats/input_file.h"
#include "data_tools/formats/obj_io.h"
#include "data_tools/formats/pmx_import.h"
#include "data_tools/geometry/error.h"
#include "data_tools/geometry/lbs.h"

namespace amt {

namespace {

std::string lower_extension(const std::string& path) {
  std::string e = std::filesystem::path(path).extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return e;
}

}  // namespace

// === Loading

std::optional<std::pair<std::string, std::string>> split_dataset_spec(const std::string& spec) {
  const size_t colon = spec.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 >= spec.size()) return std::nullopt;
  const std::string file = spec.substr(0, colon);
  const std::string e = lower_extension(file);
  if (e != ".h5" && e != ".hdf5") return std::nullopt;
  return std::make_pair(file, spec.substr(colon + 1));
}

namespace {

// True for the name of a body part a rig often has beside the canonical joints (fingers, toes, eyes,
// jaw, tongue, twist and roll bones), compared in lower case: such chains are not apparel.
bool body_part_name(std::string name) {
  std::transform(name.begin(), name.end(), name.begin(),
                 [](unsigned char ch) { return static_cast<char>(std::tolower(ch)); });
  for (const char* part : {"finger", "thumb", "index", "middle", "ring", "pinky", "little", "toe", "eye", "jaw",
                           "tongue", "teeth", "twist", "roll"}) {
    if (name.find(part) != std::string::npos) return true;
  }
  return false;
}

// The apparel a rig names by its shape: the vertices with a non-zero weight on a bone that no canonical
// joint maps and that hangs in a chain (with an unmapped parent or child that is not a body part either)
// from the mapped skeleton: hair, skirt and cape chains, VRM's secondary bones. `bones` receives the
// number of such bones.
// With `springs` (a VRM's spring-bone joints, per joint 0/1), those bones are the chains instead.
std::vector<uint8_t> chain_apparel_mask(const Skeleton& file, const CanonicalRest& rest, const SparseWeights& w,
                                        const std::vector<uint8_t>& springs, int* bones,
                                        std::vector<uint8_t>* chain_bones) {
  const int J = file.num_joints();
  std::vector<uint8_t> candidate(static_cast<size_t>(J), 0), chain(static_cast<size_t>(J), 0);
  const std::set<std::string> extra(rest.extra.begin(), rest.extra.end());
  for (int j = 0; j < J; ++j) candidate[j] = extra.count(file.names[j]) && !body_part_name(file.names[j]);
  *bones = 0;
  if (springs.size() == size_t(J)) {
    chain = springs;
  } else {
    for (int j = 0; j < J; ++j) {
      const int p = file.parents[j];
      if (candidate[j] && p >= 0 && candidate[p]) chain[j] = chain[p] = 1;
    }
  }
  for (int j = 0; j < J; ++j) *bones += chain[j];
  *chain_bones = chain;
  std::vector<uint8_t> mask(static_cast<size_t>(w.num_vertices()), 0);
  for (int i = 0; i < w.num_vertices(); ++i) {
    for (int k = 0; k < kMaxInfluences; ++k) {
      const int j = w.indices(i, k);
      if (j >= 0 && j < J && w.weights(i, k) > 0.0f && chain[j]) mask[i] = 1;
    }
  }
  return mask;
}

// The bones flagged in `keep` of a file's skeleton (B bones: names, parents, rest heads) with its sparse skin
// weights, as the character's apparel bones; null when none is flagged.
std::shared_ptr<const ApparelBones> file_apparel_bones(const std::vector<std::string>& names,
                                                       const std::vector<int32_t>& parents, const MatrixX3f& heads,
                                                       const SparseWeights& w, const std::vector<uint8_t>& keep,
                                                       const MatrixXfR& response = MatrixXfR()) {
  if (std::find(keep.begin(), keep.end(), uint8_t(1)) == keep.end()) return nullptr;
  const Eigen::Matrix<int32_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> indices = w.indices;
  const MatrixXfR weights = w.weights;
  return std::make_shared<const ApparelBones>(
      select_apparel_bones(names, heads, parents, indices, weights, keep, response));
}

// The physics response of a PMX model's bones (rig_response), measured as `amt dataset build --pmx` simulates the
// model: its own rig in its own units under MMD's world; empty when the rig cannot be simulated (the apparel module
// then reads its physics as unknown).
MatrixXfR pmx_bone_response(const std::string& path) {
  try {
    const PmxCharacter c = pmx_physics_character(read_pmx(path));
    return rig_response(c.physics, pmx_simulation_settings(PmxSimulationOptions{}, path), c.scale);
  } catch (const Error&) {
    return MatrixXfR();
  }
}

}  // namespace

RuntimeCharacter load_character(const CharacterSpec& spec) {
  RuntimeCharacter c;
  SparseWeights gltf_weights;             // a skinned glTF's own weights, for its rig's apparel
  std::vector<uint8_t> springs;           // a VRM avatar's spring-bone joints
  std::shared_ptr<SpringRig> spring_rig;  // and their simulation parameters
  std::optional<JointMapFile> user_map;
  if (!spec.joint_map.empty()) user_map = read_joint_map(spec.joint_map);
  const std::string& path = spec.spec;

  if (path.rfind("generated:", 0) == 0) {
    // "generated:SEED[:VERTICES]": the dataset builder's dressed stylized character.
    unsigned long long seed = 0;
    int vertices = 8000;
    char tail = 0;
    const int got = std::sscanf(path.c_str() + 10, "%llu:%d%c", &seed, &vertices, &tail);
    AMT_CHECK(got == 1 || got == 2, path, ": character: expected generated:SEED or generated:SEED:VERTICES");
    AMT_CHECK(vertices >= 2000 && vertices <= 200000, path, ": character: expected 2000 to 200000 vertices, found ",
              vertices);
    const GeneratedBody body = generate_body(sample_body_params(uint64_t(seed)), int(vertices * 0.7));
    const DressedCharacter dressed = dress_character(body, uint64_t(seed));
    c.name = "generated_" + std::to_string(seed);
    c.mesh = dressed.mesh;
    c.rig_apparel_mask = dressed.apparel_mask;
    c.rig_apparel = "the dressed character's simulated apparel bones";
    c.file_skeleton = body.skeleton;
    c.rest = canonical_rest(c.file_skeleton, user_map, path);
    c.skeleton = c.rest.skeleton;
    return c;
  }
  if (const auto ds = split_dataset_spec(path)) {
    DatasetReader reader(ds->first);
    AMT_CHECK(reader.has_character(ds->second), ds->first, ": /characters/", ds->second,
              ": expected a character of the dataset, found none (it has ", reader.character_names().size(),
              " characters", reader.character_names().empty() ? "" : ", e.g. " + reader.character_names()[0], ")");
    CharacterData data = reader.read_character(ds->second);
    c.name = data.name;
    c.mesh = std::move(data.mesh);
    c.file_skeleton = data.skeleton;
    c.apparel_mask = std::move(data.apparel_mask);
    c.rig_apparel_mask = c.apparel_mask;
    c.rig_apparel = "the dataset's ground truth";
    if (std::optional<ApparelBones> bones = rig_apparel_bones(data))
      c.rig_bones = std::make_shared<const ApparelBones>(std::move(*bones));
    c.dataset = ds->first;
    c.dataset_character = ds->second;
  } else {
    AMT_CHECK(std::filesystem::exists(path), path, ": character: expected a file, found none");
    c.name = std::filesystem::path(path).stem().string();
    const std::string e = lower_extension(path);
    bool has_skeleton = true;
    if (e == ".glb" || e == ".gltf" || e == ".vrm") {  // a VRM avatar is a GLB
      const GltfAsset asset = read_gltf(path);
      try {
        GltfCharacter g = gltf_character(asset);
        // A VRM avatar names its humanoid bones: they map it (under the user's own map, which wins).
        if (std::optional<JointMapFile> vrm = gltf_vrm_joint_map(asset, g)) {
          if (user_map) {
            for (const auto& entry : user_map->entries) {
              auto& e = vrm->entries;
              e.erase(std::remove_if(e.begin(), e.end(), [&](const auto& v) { return v.first == entry.first; }),
                      e.end());
              e.push_back(entry);
            }
          }
          user_map = std::move(vrm);
          springs = gltf_vrm_spring_joints(asset, g);
          SpringRig rig = gltf_vrm_spring_rig(asset, g);
          if (rig.num_joints() > 0) spring_rig = std::make_shared<SpringRig>(std::move(rig));
          c.file_kind = "VRM " + gltf_vrm_version(asset) + (gltf_vrm_version(asset) == "0" ? ".x" : ".0");
        }
        c.mesh = std::move(g.mesh);
        c.file_skeleton = std::move(g.skeleton);
        gltf_weights = std::move(g.weights);
      } catch (const Error&) {
        // No skinned mesh: an unrigged glTF needs a joints file; take the displayed mesh.
        if (spec.joints.empty()) throw;
        const GltfVertexAnimation still = gltf_vertex_animation(asset, "", 30.0f);
        c.mesh.V = still.frames.at(0);
        c.mesh.F = still.faces;
        has_skeleton = false;
      }
    } else if (e == ".obj") {
      c.mesh = read_obj(path);
      has_skeleton = false;
      if (spec.joints.empty()) {
        const std::string sidecar = joints_sidecar_path(path);
        AMT_CHECK(std::filesystem::exists(sidecar), path, ": joints: the character has no skeleton: expected ", sidecar,
                  " beside it or --character-joints FILE");
        c.file_skeleton = read_joints_json(sidecar);
        has_skeleton = true;
      }
    } else if (e == ".pmx") {
      const PmxModel model = pmx_to_amt_frame(read_pmx(path), kPmxMetresPerUnit);
      c.mesh = pmx_mesh(model);
      int simulated = 0;
      std::vector<uint8_t> rig = pmx_physics_apparel_mask(model, &simulated);
      const auto driven = std::count(rig.begin(), rig.end(), uint8_t(1));
      if (driven > 0) {
        c.rig_apparel_mask = std::move(rig);
        c.rig_apparel = "PMX physics: " + std::to_string(driven) + " vertices on bones that " +
                        std::to_string(simulated) + " simulated rigid bodies drive";
        const int B = static_cast<int>(model.bones.size());
        std::vector<std::string> names(static_cast<size_t>(B));
        std::vector<int32_t> parents(static_cast<size_t>(B));
        MatrixX3f heads(B, 3);
        for (int b = 0; b < B; ++b) {
          names[b] = model.bones[b].name;
          parents[b] = model.bones[b].parent;
          heads.row(b) = model.bones[b].position.transpose();
        }
        const SparseWeights weights = pmx_skin_weights(model);
        const std::vector<uint8_t> keep = pmx_physics_driven_bones(model);
        c.rig_bones = file_apparel_bones(names, parents, heads, weights, keep);
        if (c.rig_bones) {
          c.rig_bones_with_response = [names, parents, heads, weights, keep, path] {
            return file_apparel_bones(names, parents, heads, weights, keep, pmx_bone_response(path));
          };
        }
      }
      c.file_skeleton = pmx_skeleton(model);  // names made unique: PMX allows repeats
      if (spec.joints.empty()) c.file_weights = pmx_skin_weights(model);
      AMT_CHECK(!model.bones.empty() || !spec.joints.empty(), path,
                ": joints: the character has no skeleton (no bones): expected --character-joints FILE");
      has_skeleton = !model.bones.empty();
    } else {
      fail(path, ": character: expected a .glb, .gltf, .vrm, .obj, .pmx file or file.h5:character, found extension '",
           e, "'");
    }
    if (!spec.joints.empty()) {
      c.file_skeleton = read_joints_json(spec.joints);
      has_skeleton = true;
    }
    AMT_CHECK(has_skeleton, path, ": joints: the character has no skeleton: expected --character-joints FILE");
  }
  validate_mesh(c.mesh, path);
  AMT_CHECK(c.file_skeleton.num_joints() > 0, path,
            ": joints: the character has no skeleton: expected a rigged file or --character-joints FILE");
  c.rest = canonical_rest(c.file_skeleton, user_map, path);
  // amt's characters face +Z with their left on +X (as the motions do); one that faces -Z (its left hip on -X:
  // VRM 0.x avatars, some glTF exports) would move mirrored through every motion, so it turns half a turn about Y.
  if (c.rest.skeleton.rest_joints(kLeftHip, 0) < c.rest.skeleton.rest_joints(kRightHip, 0)) {
    for (MatrixX3f* points : {&c.mesh.V, &c.file_skeleton.rest_joints}) {
      points->col(0) *= -1.0f;
      points->col(2) *= -1.0f;
    }
    c.rest = canonical_rest(c.file_skeleton, user_map, path);
    c.turned = true;
    if (spring_rig) turn_spring_rig(*spring_rig);
  }
  if (gltf_weights.num_vertices() == c.mesh.num_vertices() && spec.joints.empty()) {
    c.file_weights = gltf_weights;
    if (spring_rig) c.springs = std::move(spring_rig);
  }
  c.skeleton = c.rest.skeleton;
  if (gltf_weights.num_vertices() == c.mesh.num_vertices()) {
    int chain_bones = 0;
    std::vector<uint8_t> chain;
    std::vector<uint8_t> rig = chain_apparel_mask(c.file_skeleton, c.rest, gltf_weights, springs, &chain_bones, &chain);
    const auto count = std::count(rig.begin(), rig.end(), uint8_t(1));
    if (count > 0) {
      MatrixX3f heads(c.file_skeleton.num_joints(), 3);
      for (int j = 0; j < c.file_skeleton.num_joints(); ++j) heads.row(j) = c.file_skeleton.rest_joints.row(j);
      c.rig_bones = file_apparel_bones(c.file_skeleton.names, c.file_skeleton.parents, heads, gltf_weights, chain);
      const std::shared_ptr<const SpringRig> rig_springs = c.springs ? c.springs : spring_rig;
      if (c.rig_bones && rig_springs) {
        // How lively a VRM avatar's springs are, on the skeleton they run on; a rig that cannot be simulated leaves
        // it unknown (--apparel spring-bones names its fault).
        c.rig_bones_with_response = [skeleton = c.file_skeleton, springs = *rig_springs, heads, weights = gltf_weights,
                                     chain] {
          MatrixXfR response;
          try {
            response = spring_response(skeleton, springs);
          } catch (const Error&) {
            response = MatrixXfR();
          }
          return file_apparel_bones(skeleton.names, skeleton.parents, heads, weights, chain, response);
        };
      }
      c.rig_apparel_mask = std::move(rig);
      c.rig_apparel = springs.empty()
                          ? "glTF chains: " + std::to_string(count) + " vertices on " + std::to_string(chain_bones) +
                                " bones outside the canonical map that hang in chains from it"
                          : "VRM spring bones: " + std::to_string(count) + " vertices on " +
                                std::to_string(chain_bones) + " bones that its springs move";
    }
  }
  return c;
}

std::vector<uint8_t> read_apparel_mask(const std::string& path, int num_vertices) {
  check_input_file(path, "an apparel mask");
  std::ifstream in(path);
  AMT_CHECK(in.good(), path, ": apparel mask: expected a readable file, found none");
  std::stringstream text;
  text << in.rdbuf();
  const std::string s = text.str();
  std::vector<double> values;
  const size_t first = s.find_first_not_of(" \t\r\n");
  if (first != std::string::npos && s[first] == '[') {
    nlohmann::json j;
    try {
      j = nlohmann::json::parse(s);
    } catch (const std::exception& e) {
      fail(path, ": apparel mask: expected a JSON array of 0/1, found invalid JSON (", e.what(), ")");
    }
    for (const auto& v : j) {
      if (v.is_boolean()) {
        values.push_back(v.get<bool>() ? 1.0 : 0.0);
      } else {
        AMT_CHECK(v.is_number(), path, ": apparel mask: expected numbers 0 or 1, found ", v.dump());
        values.push_back(v.get<double>());
      }
    }
  } else {
    std::istringstream words(s);
    std::string w;
    while (words >> w) {
      char* end = nullptr;
      const double v = std::strtod(w.c_str(), &end);
      AMT_CHECK(end && *end == '\0', path, ": apparel mask: value ", values.size(), ": expected 0 or 1, found '", w,
                "'");
      values.push_back(v);
    }
  }
  AMT_CHECK(int(values.size()) == num_vertices, path, ": apparel mask: expected ", num_vertices,
            " values (one per character vertex), found ", values.size());
  std::vector<uint8_t> mask(values.size());
  for (size_t i = 0; i < values.size(); ++i) {
    AMT_CHECK(values[i] == 0.0 || values[i] == 1.0, path, ": apparel mask: value ", i, ": expected 0 or 1, found ",
              values[i]);
    mask[i] = uint8_t(values[i]);
  }
  return mask;
}

MatrixXfR canonical_file_weights(const RuntimeCharacter& c) {
  const int N = c.mesh.num_vertices();
  const SparseWeights& fw = c.file_weights;
  if (fw.num_vertices() != N || N == 0) return MatrixXfR();
  MatrixXfR W = MatrixXfR::Zero(N, kCanonicalJointCount);
  for (int i = 0; i < N; ++i) {
    for (int k = 0; k < fw.indices.cols(); ++k) {
      const int b = fw.indices(i, k);
      if (b >= 0 && b < int(c.rest.carrier.size()) && fw.weights(i, k) > 0)
        W(i, c.rest.carrier[size_t(b)]) += fw.weights(i, k);
    }
    const float sum = W.row(i).sum();
    if (sum > 0) W.row(i) /= sum;
  }
  return W;
}

}  // namespace amt
