// A PMX model as glTF 2.0 / VRM 1.0 with VRMC_springBone (see pmx_gltf.h for what is written and why).
#include "data_tools/formats/pmx_gltf.h"

// tinygltf is Debian's libtinygltf (linked by data_tools/formats/CMakeLists.txt), built with its default options:
// no TINYGLTF_* option macros may be defined before including it (as in gltf_export.cpp).
#include <tiny_gltf.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "amt/version.h"
#include "data_tools/formats/atomic_file.h"
#include "data_tools/formats/gltf_buffer.h"
#include "data_tools/geometry/error.h"
#include "data_tools/geometry/mesh.h"

namespace amt {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr float kPi = 3.14159265359f;
constexpr float kTwoPi = 2.0f * kPi;

// Lengths below this (metres) are no length: a tail on its head.
constexpr float kNoLength = 1e-4f;

float median3(float a, float b, float c) {
  return std::max(std::min(a, b), std::min(std::max(a, b), c));
}

// Per bone, the index of the first rigid body in mode 1 or 2 on it, or -1.
std::vector<int> driven_bodies(const PmxModel& m) {
  std::vector<int> out(m.bones.size(), -1);
  for (size_t r = 0; r < m.rigid_bodies.size(); ++r) {
    const PmxRigidBody& body = m.rigid_bodies[r];
    if (body.mode == PmxPhysicsMode::kFollowBone || body.bone < 0 || size_t(body.bone) >= out.size()) continue;
    if (out[size_t(body.bone)] < 0) out[size_t(body.bone)] = int(r);
  }
  return out;
}

std::vector<std::vector<int>> bone_children(const PmxModel& m) {
  std::vector<std::vector<int>> out(m.bones.size());
  for (size_t b = 0; b < m.bones.size(); ++b) {
    if (m.bones[b].parent >= 0) out[size_t(m.bones[b].parent)].push_back(int(b));
  }
  return out;
}

// The radius of the sphere a spring joint's tail carries for a body: a sphere's or capsule's radius, a box's
// smallest half extent.
float hit_radius(const PmxRigidBody& r) {
  return r.shape == PmxShape::kBox ? r.size.minCoeff() : r.size.x();
}

PmxSpringParameters parameters_of_body(const PmxModel& m, int body) {
  const PmxRigidBody& r = m.rigid_bodies[size_t(body)];
  const float damping = std::clamp(0.5f * (r.linear_damping + r.angular_damping), 0.0f, 1.0f);
  const PmxJoint* joint = nullptr;
  for (const PmxJoint& j : m.joints) {
    if (j.rigid_body_b == body) {
      joint = &j;
      break;
    }
  }
  for (size_t k = 0; joint == nullptr && k < m.joints.size(); ++k) {
    if (m.joints[k].rigid_body_a == body) joint = &m.joints[k];
  }
  float spring = 0.0f, range = kTwoPi;
  if (joint != nullptr) {
    const Eigen::Vector3f k = joint->spring_angular.cwiseAbs();
    spring = median3(k.x(), k.y(), k.z());
    float ranges[3];
    for (int a = 0; a < 3; ++a) {
      const float width = joint->angular_max[a] - joint->angular_min[a];
      ranges[a] = width >= 0.0f ? std::min(width, kTwoPi) : kTwoPi;
    }
    range = median3(ranges[0], ranges[1], ranges[2]);
  }
  PmxSpringParameters p = pmx_spring_parameters(damping, spring, range);
  p.hit_radius = hit_radius(r);
  return p;
}

// Where a leaf bone's tail is (model frame), or nothing.
std::optional<Eigen::Vector3f> leaf_tail(const PmxModel& m, int b, int body) {
  const PmxBone& bone = m.bones[size_t(b)];
  std::optional<Eigen::Vector3f> tail;
  if (!bone.tail_is_bone) {
    tail = bone.position + bone.tail_offset;
  } else if (bone.tail_bone >= 0 && bone.tail_bone != b) {
    tail = m.bones[size_t(bone.tail_bone)].position;
  }
  if (tail && (*tail - bone.position).norm() >= kNoLength) return tail;
  if (body >= 0) {
    const Eigen::Vector3f along = m.rigid_bodies[size_t(body)].position - bone.position;
    if (along.norm() >= kNoLength) return Eigen::Vector3f(bone.position + 2.0f * along);
  }
  return std::nullopt;
}

}  // namespace

// === Spring bones

PmxSpringParameters pmx_spring_parameters(float damping, float angular_spring, float angular_range) {
  const float d = std::isfinite(damping) ? std::clamp(damping, 0.0f, 1.0f) : 0.0f;
  const float k = std::isfinite(angular_spring) ? std::max(angular_spring, 0.0f) : 0.0f;
  const float range = std::isfinite(angular_range) ? std::clamp(angular_range, 0.1f, kTwoPi) : kTwoPi;
  PmxSpringParameters p;
  p.drag_force = 0.1f + 0.7f * d;
  p.stiffness = std::min(4.0f, 0.5f * (1.0f + std::log2(1.0f + k)) / std::sqrt(range));
  p.gravity_power = 0.25f / (1.0f + k / 10.0f);
  return p;
}

std::vector<PmxSpringChain> pmx_spring_chains(const PmxModel& model, std::vector<std::string>* notes) {
  const std::vector<int> driven = driven_bodies(model);
  const std::vector<std::vector<int>> children = bone_children(model);
  std::vector<uint8_t> has_body(model.bones.size(), 0);
  for (const PmxRigidBody& r : model.rigid_bodies) {
    if (r.bone >= 0 && size_t(r.bone) < has_body.size()) has_body[size_t(r.bone)] = 1;
  }
  std::vector<int> starts;
  for (size_t b = 0; b < model.bones.size(); ++b) {
    const int p = model.bones[b].parent;
    if (driven[b] >= 0 && (p < 0 || driven[size_t(p)] < 0)) starts.push_back(int(b));
  }
  std::vector<PmxSpringChain> chains;
  std::vector<std::string> still;               // first bones of chains that turn nothing
  for (size_t s = 0; s < starts.size(); ++s) {  // branches append to starts
    PmxSpringChain chain;
    for (int b = starts[s];;) {
      chain.bones.push_back(b);
      chain.parameters.push_back(parameters_of_body(model, driven[size_t(b)]));
      std::vector<int> next;
      for (int c : children[size_t(b)]) {
        if (driven[size_t(c)] >= 0) next.push_back(c);
      }
      if (!next.empty()) {
        starts.insert(starts.end(), next.begin() + 1, next.end());
        b = next.front();
        continue;
      }
      // A leaf: a bone without a body below it is the tail, else a tip node at the leaf's tail, else none.
      const auto bodiless =
          std::find_if(children[size_t(b)].begin(), children[size_t(b)].end(), [&](int c) { return !has_body[c]; });
      if (bodiless != children[size_t(b)].end()) {
        chain.bones.push_back(*bodiless);
      } else if (const auto tail = leaf_tail(model, b, driven[size_t(b)])) {
        chain.tip = true;
        chain.tip_position = *tail;
      } else {
        chain.parameters.pop_back();  // the leaf only ends the segment before it
      }
      break;
    }
    if (chain.parameters.empty()) {
      still.push_back(model.bones[size_t(chain.bones.front())].name);
      continue;
    }
    chains.push_back(std::move(chain));
  }
  std::sort(chains.begin(), chains.end(),
            [](const PmxSpringChain& a, const PmxSpringChain& b) { return a.bones.front() < b.bones.front(); });
  if (notes != nullptr && !still.empty()) {
    std::string names;
    for (size_t k = 0; k < still.size() && k < 5; ++k) names += (k ? ", " : "") + still[k];
    if (still.size() > 5) names += ", ...";
    notes->push_back(std::to_string(still.size()) +
                     " physics bone(s) with neither a child nor a tail to turn towards (" + names + "): no spring");
  }
  return chains;
}

std::vector<PmxSpringCollider> pmx_spring_colliders(const PmxModel& model) {
  std::vector<PmxSpringCollider> out;
  for (size_t i = 0; i < model.rigid_bodies.size(); ++i) {
    const PmxRigidBody& r = model.rigid_bodies[i];
    if (r.mode != PmxPhysicsMode::kFollowBone || r.bone < 0 || size_t(r.bone) >= model.bones.size()) continue;
    PmxSpringCollider c;
    c.body = int(i);
    c.bone = r.bone;
    const Eigen::Matrix3f R = pmx_euler_rotation(r.rotation);
    const Eigen::Vector3f centre = r.position - model.bones[size_t(r.bone)].position;
    c.offset = c.tail = centre;
    c.radius = r.size.x();
    if (r.shape == PmxShape::kCapsule && r.size.y() > 0.0f) {
      c.capsule = true;
      c.offset = centre - 0.5f * r.size.y() * R.col(1);
      c.tail = centre + 0.5f * r.size.y() * R.col(1);
    } else if (r.shape == PmxShape::kBox) {
      // The covering capsule runs along the longest half extent, its radius the diagonal of the other two.
      int a = 0;
      r.size.maxCoeff(&a);
      const float along = r.size[a];
      const float across = std::sqrt(r.size.squaredNorm() - along * along);
      const float capsule_volume = kPi * across * across * (2.0f * along + 4.0f / 3.0f * across);
      const float sphere_volume = 4.0f / 3.0f * kPi * std::pow(r.size.norm(), 3.0f);
      if (capsule_volume < sphere_volume && along > 0.0f) {
        c.capsule = true;
        c.offset = centre - along * R.col(a);
        c.tail = centre + along * R.col(a);
        c.radius = across;
      } else {
        c.radius = r.size.norm();
      }
    }
    out.push_back(c);
  }
  return out;
}

// === VRM humanoid

namespace {

// VRM 1.0 humanoid bones amt writes, in hierarchy order: (name, its VRM parent, required).
struct HumanBone {
  const char* name;
  const char* parent;
  bool required;
};
constexpr HumanBone kHumanBones[] = {
    {"hips", nullptr, true},
    {"spine", "hips", true},
    {"chest", "spine", false},
    {"upperChest", "chest", false},
    {"neck", "upperChest", false},
    {"head", "neck", true},
    {"leftUpperLeg", "hips", true},
    {"leftLowerLeg", "leftUpperLeg", true},
    {"leftFoot", "leftLowerLeg", true},
    {"leftToes", "leftFoot", false},
    {"rightUpperLeg", "hips", true},
    {"rightLowerLeg", "rightUpperLeg", true},
    {"rightFoot", "rightLowerLeg", true},
    {"rightToes", "rightFoot", false},
    {"leftShoulder", "upperChest", false},
    {"leftUpperArm", "leftShoulder", true},
    {"leftLowerArm", "leftUpperArm", true},
    {"leftHand", "leftLowerArm", true},
    {"rightShoulder", "upperChest", false},
    {"rightUpperArm", "rightShoulder", true},
    {"rightLowerArm", "rightUpperArm", true},
    {"rightHand", "rightLowerArm", true},
};

const HumanBone* human_bone(const std::string& name) {
  for (const HumanBone& h : kHumanBones) {
    if (name == h.name) return &h;
  }
  return nullptr;
}

// The canonical joint each VRM bone takes its bone from (the spine bones aside).
const std::map<std::string, int>& canonical_of_human_bone() {
  static const std::map<std::string, int> map = {{"hips", kPelvis},
                                                 {"neck", kNeck},
                                                 {"head", kHead},
                                                 {"leftUpperLeg", kLeftHip},
                                                 {"leftLowerLeg", kLeftKnee},
                                                 {"leftFoot", kLeftAnkle},
                                                 {"leftToes", kLeftFoot},
                                                 {"rightUpperLeg", kRightHip},
                                                 {"rightLowerLeg", kRightKnee},
                                                 {"rightFoot", kRightAnkle},
                                                 {"rightToes", kRightFoot},
                                                 {"leftShoulder", kLeftCollar},
                                                 {"leftUpperArm", kLeftShoulder},
                                                 {"leftLowerArm", kLeftElbow},
                                                 {"leftHand", kLeftWrist},
                                                 {"rightShoulder", kRightCollar},
                                                 {"rightUpperArm", kRightShoulder},
                                                 {"rightLowerArm", kRightElbow},
                                                 {"rightHand", kRightWrist}};
  return map;
}

bool is_ancestor_or_self(const PmxModel& m, int ancestor, int bone) {
  for (int b = bone; b >= 0; b = m.bones[size_t(b)].parent) {
    if (b == ancestor) return true;
  }
  return false;
}

int common_ancestor(const PmxModel& m, int a, int b) {
  for (int x = a; x >= 0; x = m.bones[size_t(x)].parent) {
    if (is_ancestor_or_self(m, x, b)) return x;
  }
  return -1;
}

// The VRM bones (and MMD names) whose canonical joint no name table finds among the model's bones: what makes
// map_to_canonical fail on a model without humanoid bones. Empty when every one is there by name.
std::vector<std::string> missing_by_name(const PmxModel& m, const std::optional<JointMapFile>& joint_map) {
  std::set<std::string> names;
  for (const PmxBone& b : m.bones) names.insert(normalize_joint_name(b.name));
  std::set<int> mapped;
  if (joint_map) {
    for (const auto& entry : joint_map->entries) mapped.insert(entry.first);
  }
  std::vector<std::string> missing;
  for (const auto& [bone, joint] : canonical_of_human_bone()) {
    const HumanBone* h = human_bone(bone);
    if (!h->required && joint != kNeck) continue;  // amt's canonical skeleton needs the neck too
    bool found = mapped.count(joint) > 0;
    std::string mmd;
    for (const JointNameConvention& convention : joint_name_conventions()) {
      for (const std::string& name : convention.names[size_t(joint)]) {
        found = found || names.count(name) > 0;
        if (convention.name == "MMD" && mmd.empty()) mmd = name;
      }
    }
    if (!found) missing.push_back(bone + (mmd.empty() ? "" : " (" + mmd + ")"));
  }
  // Hierarchy order, as the VRM specification lists them.
  std::vector<std::string> ordered;
  for (const HumanBone& h : kHumanBones) {
    for (const std::string& entry : missing) {
      if (entry.rfind(h.name, 0) == 0 && (entry.size() == std::strlen(h.name) || entry[std::strlen(h.name)] == ' '))
        ordered.push_back(entry);
    }
  }
  return ordered;
}

}  // namespace

std::vector<std::pair<std::string, int>> pmx_vrm_humanoid(const PmxModel& model,
                                                          const std::optional<JointMapFile>& joint_map,
                                                          std::vector<std::string>* notes) {
  const std::string& src = model.source;
  std::vector<std::string> names;
  std::vector<int> parents;
  for (const PmxBone& b : model.bones) {
    names.push_back(b.name);
    parents.push_back(b.parent);
  }
  JointMapping mapping;
  try {
    mapping = map_to_canonical(names, parents, joint_map, src);
  } catch (const Error&) {
    const std::vector<std::string> missing = missing_by_name(model, joint_map);
    if (missing.empty()) throw;
    std::string list;
    for (size_t k = 0; k < missing.size(); ++k) list += (k ? ", " : "") + missing[k];
    fail(src, ": humanoid: expected a bone for each of the VRM humanoid bones ", list,
         " (MMD's standard names in brackets), found none among the model's ", model.bones.size(),
         " bones; write a .glb instead, or pass --joint-map FILE {canonical joint: bone}");
  }
  const auto& source = mapping.source_joint;
  std::map<std::string, int> bone_of;
  for (const auto& [bone, joint] : canonical_of_human_bone()) bone_of[bone] = source[size_t(joint)];
  // spine, chest, upperChest: the distinct spine bones above the pelvis's, in order.
  std::vector<int> spine;
  for (int joint : {kSpine1, kSpine2, kSpine3}) {
    const int b = source[size_t(joint)];
    if (b != source[kPelvis] && std::find(spine.begin(), spine.end(), b) == spine.end()) spine.push_back(b);
  }
  const char* spine_names[3] = {"spine", "chest", "upperChest"};
  for (size_t k = 0; k < 3; ++k) bone_of[spine_names[k]] = k < spine.size() ? spine[k] : -1;
  const auto label = [&](int b) { return "'" + model.bones[size_t(b)].name + "'"; };
  AMT_CHECK(bone_of["spine"] >= 0, src, ": humanoid: expected a spine bone between the hips ", label(bone_of["hips"]),
            " and the neck ", label(bone_of["neck"]), " for the VRM humanoid bone spine, found none");
  // MMD hangs 下半身 (the pelvis) and 上半身 (the spine) side by side from センター: the hips are then above both.
  if (!is_ancestor_or_self(model, bone_of["hips"], bone_of["spine"])) {
    const int above = common_ancestor(model, bone_of["hips"], bone_of["spine"]);
    AMT_CHECK(above >= 0, src, ": humanoid: expected the spine ", label(bone_of["spine"]), " below the hips ",
              label(bone_of["hips"]), ", found them in separate hierarchies");
    if (notes != nullptr) {
      notes->push_back("humanoid: hips on " + label(above) + ", above both " + label(bone_of["hips"]) +
                       " (the pelvis) and " + label(bone_of["spine"]) + " (the spine), which hang side by side");
    }
    bone_of["hips"] = above;
  }
  std::vector<std::pair<std::string, int>> out;
  std::map<int, std::string> taken;  // bone -> VRM bone
  std::map<std::string, int> assigned;
  for (const HumanBone& h : kHumanBones) {
    const int b = bone_of[h.name];
    if (b < 0) continue;
    if (taken.count(b)) {
      AMT_CHECK(!h.required, src, ": humanoid: expected a bone of its own for the VRM humanoid bone ", h.name,
                ", found ", label(b), ", which is already ", taken[b]);
      continue;
    }
    // The humanoid bone the specification hangs it from (skipping optional ones that are absent), against the
    // nearest humanoid bone above it in the model.
    std::string expected;
    for (const char* p = h.parent; p != nullptr; p = human_bone(p)->parent) {
      if (assigned.count(p)) {
        expected = p;
        break;
      }
    }
    std::string actual;
    for (int a = model.bones[size_t(b)].parent; a >= 0 && actual.empty(); a = model.bones[size_t(a)].parent) {
      if (taken.count(a)) actual = taken[a];
    }
    if (actual != expected) {
      AMT_CHECK(!h.required, src, ": humanoid: expected the VRM humanoid bone ", h.name, " on ", label(b), " below ",
                expected.empty() ? std::string("no other humanoid bone") : expected, ", found it below ",
                actual.empty() ? std::string("none") : actual);
      if (notes != nullptr) {
        notes->push_back("humanoid: " + std::string(h.name) + " left out: its bone " + label(b) + " is below " +
                         (actual.empty() ? std::string("no humanoid bone") : actual) + ", VRM wants it below " +
                         expected);
      }
      continue;
    }
    taken[b] = h.name;
    assigned[h.name] = b;
    out.emplace_back(h.name, b);
  }
  for (const HumanBone& h : kHumanBones) {
    AMT_CHECK(!h.required || assigned.count(h.name), src, ": humanoid: expected a bone for the VRM humanoid bone ",
              h.name, ", found none");
  }
  return out;
}

// === Conversion

namespace {

// --- Textures

// The lower-case ASCII form of a file name, for the letter-case fallback.
std::string lower_ascii(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return s;
}

// A texture read for embedding: its bytes and MIME type, or why it cannot be embedded.
struct TextureFile {
  std::string bytes;
  std::string mime_type;  // "image/png" or "image/jpeg" when embeddable
  std::string problem;    // else one phrase: "BMP cannot go into glTF (only PNG and JPEG can)", "not found", ...
};

constexpr uintmax_t kMaxTextureBytes = uintmax_t(64) << 20;

TextureFile read_texture(const fs::path& folder, const std::string& raw) {
  TextureFile out;
  std::string text = raw;
  std::replace(text.begin(), text.end(), '\\', '/');
  const fs::path relative = fs::path(text).lexically_normal();
  if (text.empty() || relative.empty()) {
    out.problem = "an empty path";
    return out;
  }
  if (relative.is_absolute() || relative.has_root_name() || *relative.begin() == "..") {
    out.problem = "outside the model's folder (only files in it or below it are read)";
    return out;
  }
  // Each component as it is, else one that differs only in letter case.
  fs::path at = folder;
  std::error_code ec;
  for (const fs::path& part : relative) {
    if (part == ".") continue;
    if (fs::exists(at / part, ec)) {
      at /= part;
      continue;
    }
    fs::path match;
    for (fs::directory_iterator it(at, ec), end; !ec && it != end; it.increment(ec)) {
      if (lower_ascii(it->path().filename().string()) == lower_ascii(part.string())) {
        match = it->path().filename();
        break;
      }
    }
    if (match.empty()) {
      out.problem = "not found in " + folder.string();
      return out;
    }
    at /= match;
  }
  if (!fs::is_regular_file(at, ec)) {
    out.problem = "not a regular file";
    return out;
  }
  const uintmax_t size = fs::file_size(at, ec);
  if (ec || size > kMaxTextureBytes) {
    out.problem = "larger than 64 MiB";
    return out;
  }
  std::ifstream in(at, std::ios::binary);
  std::ostringstream bytes;
  bytes << in.rdbuf();
  out.bytes = bytes.str();
  const std::string& b = out.bytes;
  const auto starts = [&](const char* magic, size_t n) {
    return b.size() >= n && std::memcmp(b.data(), magic, n) == 0;
  };
  const std::string extension = lower_ascii(at.extension().string());
  if (!in.good() && !in.eof()) {
    out.problem = "cannot be read";
  } else if (starts("\x89PNG\r\n\x1a\n", 8)) {
    out.mime_type = "image/png";
  } else if (starts("\xFF\xD8\xFF", 3)) {
    out.mime_type = "image/jpeg";
  } else if (starts("BM", 2)) {
    out.problem = "BMP cannot go into glTF (only PNG and JPEG can)";
  } else if (starts("DDS ", 4)) {
    out.problem = "DDS cannot go into glTF (only PNG and JPEG can)";
  } else if (extension == ".tga") {
    out.problem = "TGA cannot go into glTF (only PNG and JPEG can)";
  } else {
    out.problem = "not a PNG or JPEG file (only those can go into glTF)";
  }
  if (out.mime_type.empty()) out.bytes.clear();
  return out;
}

// --- The glTF model

tinygltf::Value to_value(const json& j) {
  switch (j.type()) {
    case json::value_t::boolean:
      return tinygltf::Value(j.get<bool>());
    case json::value_t::number_integer:
    case json::value_t::number_unsigned:
      return tinygltf::Value(j.get<int>());
    case json::value_t::number_float:
      return tinygltf::Value(j.get<double>());
    case json::value_t::string:
      return tinygltf::Value(j.get<std::string>());
    case json::value_t::array: {
      tinygltf::Value::Array a;
      for (const json& e : j) a.push_back(to_value(e));
      return tinygltf::Value(std::move(a));
    }
    case json::value_t::object: {
      tinygltf::Value::Object o;
      for (auto it = j.begin(); it != j.end(); ++it) o[it.key()] = to_value(it.value());
      return tinygltf::Value(std::move(o));
    }
    default:
      return tinygltf::Value();
  }
}

json vec3(const Eigen::Vector3f& v) {
  return json::array({double(v.x()), double(v.y()), double(v.z())});
}

// --- VRM meta

// The authors named in a PMX comment: on the first line with an author marker followed by a separator ("作者：",
// "Model by "), the text after it; "" when there is none.
std::string author_of(const std::string& comment) {
  static const char* const kMarkers[] = {"作者",       "制作",        "製作",     "モデリング", "authors",   "author",
                                         "modeled by", "modelled by", "model by", "made by",    "created by"};
  static const char* const kSeparators[] = {":", "：", " ", "　", "-", "\t"};
  const auto skip_separators = [](std::string& text) {
    bool any = false;
    for (bool again = true; again;) {
      again = false;
      for (const char* sep : kSeparators) {
        if (text.rfind(sep, 0) == 0) {
          text.erase(0, std::strlen(sep));
          again = any = true;
        }
      }
    }
    return any;
  };
  std::istringstream lines(comment);
  for (std::string line; std::getline(lines, line);) {
    const std::string lower = lower_ascii(line);
    for (const char* marker : kMarkers) {
      const size_t at = lower.find(marker);
      if (at == std::string::npos) continue;
      std::string rest = line.substr(at + std::strlen(marker));
      if (!skip_separators(rest)) continue;
      while (!rest.empty() && (rest.back() == '\r' || rest.back() == ' ' || rest.back() == '\t')) rest.pop_back();
      if (rest.size() > 200) {
        size_t cut = 200;
        while (cut > 0 && (static_cast<unsigned char>(rest[cut]) & 0xC0) == 0x80) --cut;  // a UTF-8 boundary
        rest.resize(cut);
      }
      if (!rest.empty()) return rest;
    }
  }
  return "";
}

json vrm_extension(const PmxModel& m, const std::string& path, const std::vector<std::pair<std::string, int>>& human) {
  std::string name = m.header.name.empty() ? m.header.name_english : m.header.name;
  if (name.empty()) name = fs::path(m.source.empty() ? path : m.source).stem().string();
  std::string author = author_of(m.header.comment);
  if (author.empty()) author = author_of(m.header.comment_english);
  if (author.empty()) author = "unknown";
  json meta = {{"name", name},
               {"authors", json::array({author})},
               {"licenseUrl", "https://vrm.dev/licenses/1.0/"},
               {"avatarPermission", "onlyAuthor"},
               {"allowExcessivelyViolentUsage", false},
               {"allowExcessivelySexualUsage", false},
               {"commercialUsage", "personalNonProfit"},
               {"allowPoliticalOrReligiousUsage", false},
               {"allowAntisocialOrHateUsage", false},
               {"creditNotation", "required"},
               {"allowRedistribution", false},
               {"modification", "prohibited"}};
  json extras = json::object();
  if (!m.header.comment.empty()) extras["pmx_comment"] = m.header.comment;
  if (!m.header.comment_english.empty()) extras["pmx_comment_english"] = m.header.comment_english;
  if (!extras.empty()) meta["extras"] = extras;
  json bones = json::object();
  for (const auto& [bone, index] : human) bones[bone] = {{"node", 1 + index}};
  return {{"specVersion", "1.0"}, {"meta", meta}, {"humanoid", {{"humanBones", bones}}}};
}

}  // namespace

PmxGltfSummary write_pmx_gltf(const PmxModel& input, const std::string& path, const PmxGltfOptions& options) {
  AMT_CHECK(std::isfinite(options.metres_per_unit) && options.metres_per_unit > 0, path,
            ": metres per unit: expected a finite number > 0, found ", options.metres_per_unit);
  const PmxModel m = input.frame == PmxFrame::kMmd ? pmx_to_amt_frame(input, options.metres_per_unit) : input;
  const bool vrm = options.kind == PmxGltfKind::kVrm;
  PmxGltfSummary summary;
  std::vector<std::string>& notes = summary.notes;
  std::vector<std::pair<std::string, int>> human;
  if (vrm) human = pmx_vrm_humanoid(m, options.joint_map, &notes);  // before any work: its errors come first

  const int V = m.vertices.size(), F = int(m.faces.rows()), J = int(m.bones.size());
  AMT_CHECK(F > 0, m.source, ": faces: expected at least 1 face to convert, found none");
  AMT_CHECK(J <= 65536, m.source,
            ": bones: expected at most 65536 bones (glTF's JOINTS_0 holds 16-bit indices), found ", J);
  summary.pmx_vertices = V;
  summary.faces = F;
  summary.bones = J;
  tinygltf::Model model;
  model.asset.version = "2.0";
  model.asset.generator = std::string("amt ") + AMT_VERSION;
  model.asset.extras =
      to_value(json{{"amt_format", "converted-pmx"}, {"amt_format_version", 1}, {"metres_per_unit", double(m.scale)}});
  GltfBuffer buffer(model);

  // --- Materials and their textures
  const fs::path folder =
      options.texture_folder.empty() ? fs::path(m.source).parent_path() : fs::path(options.texture_folder);
  std::map<int, int> texture_of;                  // PMX texture -> glTF texture, or -1 when left out
  std::map<int, std::vector<std::string>> users;  // PMX texture -> materials naming it
  for (const PmxMaterial& pm : m.materials) {
    if (pm.texture >= 0) users[pm.texture].push_back(pm.name);
  }
  const auto gltf_texture = [&](int t) {
    const auto known = texture_of.find(t);
    if (known != texture_of.end()) return known->second;
    const std::string& raw = m.textures[size_t(t)];
    const TextureFile file = read_texture(folder.empty() ? fs::path(".") : folder, raw);
    int index = -1;
    if (!file.mime_type.empty()) {
      tinygltf::Image image;
      image.name = raw;
      image.mimeType = file.mime_type;
      image.bufferView = buffer.view(file.bytes.data(), file.bytes.size(), 0);
      model.images.push_back(image);
      tinygltf::Texture texture;
      texture.source = int(model.images.size()) - 1;
      model.textures.push_back(texture);
      index = int(model.textures.size()) - 1;
      ++summary.textures_embedded;
    } else {
      const std::vector<std::string>& who = users[t];
      std::string materials;
      for (size_t k = 0; k < who.size() && k < 3; ++k) materials += (k ? ", " : "") + who[k];
      if (who.size() > 3) materials += ", ...";
      notes.push_back("texture " + raw + " (material" + (who.size() == 1 ? " " : "s ") + materials +
                      "): " + file.problem + ": left out, the colour kept");
      ++summary.textures_left_out;
    }
    texture_of[t] = index;
    return index;
  };
  const auto add_material = [&](const PmxMaterial& pm) {
    tinygltf::Material mat;
    mat.name = pm.name;
    const Eigen::Vector4f colour = pm.diffuse.cwiseMax(0.0f).cwiseMin(1.0f);
    mat.pbrMetallicRoughness.baseColorFactor = {colour[0], colour[1], colour[2], colour[3]};
    mat.pbrMetallicRoughness.metallicFactor = 0.0;
    mat.pbrMetallicRoughness.roughnessFactor = 1.0;
    mat.doubleSided = pm.double_sided();
    mat.alphaMode = colour[3] < 1.0f ? "BLEND" : "OPAQUE";
    if (pm.texture >= 0) mat.pbrMetallicRoughness.baseColorTexture.index = gltf_texture(pm.texture);
    model.materials.push_back(mat);
    return int(model.materials.size()) - 1;
  };
  int sphere = 0, toon = 0;
  for (const PmxMaterial& pm : m.materials) {
    add_material(pm);
    sphere += pm.sphere_texture >= 0 && pm.sphere_mode != PmxSphereMode::kNone;
    toon += pm.shared_toon || pm.toon >= 0;
  }

  // --- The mesh: a primitive per material's face range
  const SparseWeights weights = J > 0 ? pmx_skin_weights(m) : SparseWeights{};
  const MatrixX3f face_normals = vertex_normals(m.vertices.positions, m.faces);
  tinygltf::Mesh mesh;
  mesh.name = m.header.name;
  int first_face = 0;
  for (size_t k = 0; k <= m.materials.size() && first_face < F; ++k) {
    int material = -1, count = 0;
    if (k < m.materials.size()) {
      material = int(k);
      count = m.materials[k].face_count;
    } else {  // faces no material draws
      PmxMaterial grey;
      grey.name = "pmx_undrawn_faces";
      grey.diffuse = {0.8f, 0.8f, 0.8f, 1.0f};
      grey.flags = kPmxMaterialDoubleSided;
      material = add_material(grey);
      count = F - first_face;
      notes.push_back(std::to_string(count) + " face(s) that no PMX material draws: a grey material of their own");
    }
    if (count <= 0) continue;
    // The vertices of these faces, in PMX order.
    std::vector<int> local(size_t(V), -1), used;
    for (int f = first_face; f < first_face + count; ++f) {
      for (int c = 0; c < 3; ++c) local[size_t(m.faces(f, c))] = 0;
    }
    for (int v = 0; v < V; ++v) {
      if (local[size_t(v)] == 0) {
        local[size_t(v)] = int(used.size());
        used.push_back(v);
      }
    }
    const size_t n = used.size();
    std::vector<float> positions(3 * n), normals(3 * n), uvs(2 * n), w(4 * n, 0.0f);
    std::vector<uint16_t> joints(4 * n, 0);
    for (size_t i = 0; i < n; ++i) {
      const int v = used[i];
      Eigen::Vector3f normal = m.vertices.normals.row(v).transpose();
      if (!(normal.norm() > 1e-6f)) normal = face_normals.row(v).transpose();
      normal = normal.norm() > 1e-6f ? Eigen::Vector3f(normal.normalized()) : Eigen::Vector3f::UnitY();
      for (int c = 0; c < 3; ++c) {
        positions[3 * i + size_t(c)] = m.vertices.positions(v, c);
        normals[3 * i + size_t(c)] = normal[c];
      }
      uvs[2 * i] = m.vertices.uvs(v, 0);
      uvs[2 * i + 1] = m.vertices.uvs(v, 1);
      if (J == 0) continue;
      // Largest weight first; pmx_skin_weights merged repeated bones and normalised the row.
      std::array<std::pair<float, int>, kMaxInfluences> slots;
      for (int s = 0; s < kMaxInfluences; ++s) slots[size_t(s)] = {weights.weights(v, s), weights.indices(v, s)};
      std::stable_sort(slots.begin(), slots.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
      float sum = 0.0f;
      for (const auto& slot : slots) sum += std::max(slot.first, 0.0f);
      for (int s = 0; s < kMaxInfluences; ++s) {
        if (!(slots[size_t(s)].first > 0.0f)) continue;  // zero weights stay on joint 0
        joints[4 * i + size_t(s)] = uint16_t(slots[size_t(s)].second);
        w[4 * i + size_t(s)] = slots[size_t(s)].first / sum;
      }
    }
    tinygltf::Primitive primitive;
    primitive.mode = TINYGLTF_MODE_TRIANGLES;
    primitive.material = material;
    primitive.attributes["POSITION"] = buffer.accessor(positions, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, 3,
                                                       TINYGLTF_TARGET_ARRAY_BUFFER, true);
    primitive.attributes["NORMAL"] = buffer.accessor(normals, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, 3,
                                                     TINYGLTF_TARGET_ARRAY_BUFFER, false);
    primitive.attributes["TEXCOORD_0"] =
        buffer.accessor(uvs, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC2, 2, TINYGLTF_TARGET_ARRAY_BUFFER, false);
    if (J > 0) {
      if (J <= 256) {
        const std::vector<uint8_t> small(joints.begin(), joints.end());
        primitive.attributes["JOINTS_0"] = buffer.accessor(small, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
                                                           TINYGLTF_TYPE_VEC4, 4, TINYGLTF_TARGET_ARRAY_BUFFER, false);
      } else {
        primitive.attributes["JOINTS_0"] = buffer.accessor(joints, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
                                                           TINYGLTF_TYPE_VEC4, 4, TINYGLTF_TARGET_ARRAY_BUFFER, false);
      }
      primitive.attributes["WEIGHTS_0"] =
          buffer.accessor(w, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC4, 4, TINYGLTF_TARGET_ARRAY_BUFFER, false);
    }
    std::vector<uint32_t> indices(3 * size_t(count));
    for (int f = 0; f < count; ++f) {
      for (int c = 0; c < 3; ++c)
        indices[3 * size_t(f) + size_t(c)] = uint32_t(local[size_t(m.faces(first_face + f, c))]);
    }
    if (n <= 65535) {
      const std::vector<uint16_t> short_indices(indices.begin(), indices.end());
      primitive.indices = buffer.accessor(short_indices, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT, TINYGLTF_TYPE_SCALAR,
                                          1, TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER, false);
    } else {
      primitive.indices = buffer.accessor(indices, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, TINYGLTF_TYPE_SCALAR, 1,
                                          TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER, false);
    }
    mesh.primitives.push_back(primitive);
    summary.vertex_source.insert(summary.vertex_source.end(), used.begin(), used.end());
    first_face += count;
  }
  summary.vertices = int(summary.vertex_source.size());
  summary.primitives = int(mesh.primitives.size());
  summary.materials = int(model.materials.size());
  if (summary.vertices != V) {
    notes.push_back(std::to_string(V) + " PMX vertices written as " + std::to_string(summary.vertices) +
                    ": a vertex of two materials once in each, one of no face not at all");
  }

  // --- Nodes: the mesh, the bones, a common root, spring tips
  tinygltf::Node mesh_node;
  mesh_node.name = m.header.name.empty() ? "pmx_mesh" : m.header.name;
  if (!mesh.primitives.empty()) {
    model.meshes.push_back(mesh);
    mesh_node.mesh = 0;
  }
  model.nodes.push_back(mesh_node);
  std::vector<int> roots;
  for (int b = 0; b < J; ++b) {
    const PmxBone& bone = m.bones[size_t(b)];
    const Eigen::Vector3f offset =
        bone.parent < 0 ? bone.position : Eigen::Vector3f(bone.position - m.bones[size_t(bone.parent)].position);
    tinygltf::Node node;
    node.name = bone.name;
    node.translation = {offset.x(), offset.y(), offset.z()};
    model.nodes.push_back(node);
  }
  for (int b = 0; b < J; ++b) {
    const int p = m.bones[size_t(b)].parent;
    if (p >= 0) {
      model.nodes[size_t(p) + 1].children.push_back(b + 1);
    } else {
      roots.push_back(b + 1);
    }
  }
  tinygltf::Scene scene;
  scene.nodes = {0};
  int skeleton_root = roots.empty() ? -1 : roots.front();
  if (roots.size() > 1) {
    tinygltf::Node root;
    root.name = "pmx_root";
    root.children = roots;
    model.nodes.push_back(root);
    skeleton_root = int(model.nodes.size()) - 1;
    scene.nodes.push_back(skeleton_root);
  } else if (skeleton_root >= 0) {
    scene.nodes.push_back(skeleton_root);
  }
  if (J > 0 && !mesh.primitives.empty()) {
    tinygltf::Skin skin;
    skin.name = "pmx_bones";
    skin.skeleton = skeleton_root;
    std::vector<float> inverse_binds(16 * size_t(J), 0.0f);
    for (int b = 0; b < J; ++b) {
      skin.joints.push_back(b + 1);
      float* ibm = &inverse_binds[16 * size_t(b)];  // column-major translate(-position)
      ibm[0] = ibm[5] = ibm[10] = ibm[15] = 1.0f;
      for (int c = 0; c < 3; ++c) ibm[12 + c] = -m.bones[size_t(b)].position[c];
    }
    skin.inverseBindMatrices =
        buffer.accessor(inverse_binds, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_MAT4, 16, 0, false);
    model.skins.push_back(skin);
    model.nodes[0].skin = 0;
  }

  // --- Spring bones
  const std::vector<PmxSpringChain> chains = pmx_spring_chains(m, &notes);
  const std::vector<PmxSpringCollider> colliders = pmx_spring_colliders(m);
  json spring_extension;
  if (!chains.empty() || !colliders.empty()) {
    json collider_list = json::array(), groups = json::array(), springs = json::array();
    std::map<int, std::vector<int>> by_group;  // PMX collision group -> collider indices
    for (size_t c = 0; c < colliders.size(); ++c) {
      const PmxSpringCollider& k = colliders[c];
      json shape = k.capsule
                       ? json{{"capsule", {{"offset", vec3(k.offset)}, {"radius", k.radius}, {"tail", vec3(k.tail)}}}}
                       : json{{"sphere", {{"offset", vec3(k.offset)}, {"radius", k.radius}}}};
      collider_list.push_back({{"node", 1 + k.bone}, {"shape", shape}});
      by_group[m.rigid_bodies[size_t(k.body)].group].push_back(int(c));
    }
    std::vector<int> group_of_pmx;  // colliderGroups index -> PMX group
    for (const auto& [group, members] : by_group) {
      groups.push_back({{"name", "group " + std::to_string(group)}, {"colliders", members}});
      group_of_pmx.push_back(group);
    }
    const std::vector<int> driven = driven_bodies(m);
    for (const PmxSpringChain& chain : chains) {
      json joints = json::array();
      for (size_t k = 0; k < chain.bones.size(); ++k) {
        json joint = {{"node", 1 + chain.bones[k]}};
        if (k < chain.parameters.size()) {
          const PmxSpringParameters& p = chain.parameters[k];
          joint["hitRadius"] = p.hit_radius;
          joint["stiffness"] = p.stiffness;
          joint["gravityPower"] = p.gravity_power;
          joint["gravityDir"] = json::array({0.0, -1.0, 0.0});
          joint["dragForce"] = p.drag_force;
        }
        joints.push_back(joint);
      }
      if (chain.tip) {
        const int leaf = chain.bones.back();
        tinygltf::Node tip;
        tip.name = m.bones[size_t(leaf)].name + "_tip";
        const Eigen::Vector3f offset = chain.tip_position - m.bones[size_t(leaf)].position;
        tip.translation = {offset.x(), offset.y(), offset.z()};
        model.nodes.push_back(tip);
        model.nodes[size_t(leaf) + 1].children.push_back(int(model.nodes.size()) - 1);
        joints.push_back({{"node", int(model.nodes.size()) - 1}});
      }
      // The collider groups any body of the chain collides with under MMD's masks.
      json used = json::array();
      for (size_t g = 0; g < group_of_pmx.size(); ++g) {
        bool collides = false;
        for (int c : by_group[group_of_pmx[g]]) {
          const PmxRigidBody& fixed = m.rigid_bodies[size_t(colliders[size_t(c)].body)];
          for (size_t k = 0; k < chain.parameters.size() && !collides; ++k) {
            const PmxRigidBody& moving = m.rigid_bodies[size_t(driven[size_t(chain.bones[k])])];
            collides = ((moving.collision_mask >> fixed.group) & 1) && ((fixed.collision_mask >> moving.group) & 1);
          }
        }
        if (collides) used.push_back(int(g));
      }
      json spring = {{"name", m.bones[size_t(chain.bones.front())].name}, {"joints", joints}};
      if (!used.empty()) spring["colliderGroups"] = used;
      springs.push_back(spring);
      summary.spring_joints += int(joints.size());
      summary.spring_segments += int(chain.parameters.size());
    }
    spring_extension = {{"specVersion", "1.0"}};
    if (!collider_list.empty()) spring_extension["colliders"] = collider_list;
    if (!groups.empty()) spring_extension["colliderGroups"] = groups;
    if (!springs.empty()) spring_extension["springs"] = springs;
    summary.springs = int(chains.size());
    summary.colliders = int(colliders.size());
    summary.collider_groups = int(groups.size());
    model.extensions["VRMC_springBone"] = to_value(spring_extension);
    model.extensionsUsed.push_back("VRMC_springBone");
  }
  summary.nodes = int(model.nodes.size());
  if (vrm) {
    model.extensions["VRMC_vrm"] = to_value(vrm_extension(m, path, human));
    model.extensionsUsed.insert(model.extensionsUsed.begin(), "VRMC_vrm");
    for (const auto& [bone, index] : human) summary.humanoid.emplace_back(bone, m.bones[size_t(index)].name);
  }
  model.scenes.push_back(scene);
  model.defaultScene = 0;

  // --- What is not carried
  if (sphere > 0)
    notes.push_back("sphere textures of " + std::to_string(sphere) + " material(s): dropped (glTF has none)");
  if (toon > 0) notes.push_back("toon textures of " + std::to_string(toon) + " material(s): dropped (glTF has none)");
  if (m.morph_count > 0) notes.push_back(std::to_string(m.morph_count) + " morph(s): dropped");
  if (m.display_frame_count > 0) notes.push_back(std::to_string(m.display_frame_count) + " display frame(s): dropped");
  if (m.soft_body_count > 0) notes.push_back(std::to_string(m.soft_body_count) + " soft body(ies): dropped");
  int loose = 0;
  for (const PmxRigidBody& r : m.rigid_bodies) loose += r.bone < 0;
  if (loose > 0) notes.push_back(std::to_string(loose) + " rigid body(ies) on no bone: left out");
  if (!chains.empty()) {
    notes.push_back(
        "spring parameters approximate MMD's physics (pmx_gltf.h); joints' translation limits and "
        "springs are not carried");
  }
  if (vrm) {
    notes.push_back(
        "rest pose: the PMX's own (usually an A-pose), not VRM 1.0's T-pose; VRM meta: the most "
        "restrictive permissions, the PMX comment in meta.extras.pmx_comment");
  }

  // --- The file
  const size_t bytes = model.buffers[0].data.size();
  AMT_CHECK(bytes < (size_t(1) << 32) - (size_t(1) << 24), path,
            ": buffer: expected less than 4 GiB of data for a GLB file, found ", bytes, " bytes");
  std::ostringstream stream;
  tinygltf::TinyGLTF writer;
  AMT_CHECK(writer.WriteGltfSceneToStream(&model, stream, false, true), path,
            ": write: expected tinygltf to serialise the model, found an error");
  const std::string content = stream.str();
  write_file_atomically(path, content);
  summary.bytes = content.size();
  return summary;
}

}  // namespace amt
