#include "data_tools/formats/joint_map.h"

#include <algorithm>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <unordered_map>
#include <unordered_set>

#include "data_tools/geometry/error.h"
#include "data_tools/formats/input_file.h"

namespace amt {

namespace {

// === Helpers

bool is_separator(char c) {
  return c == ' ' || c == '_' || c == '-' || c == '.' || c == '\t';
}

// The joint on the other side of the body (a central joint is its own mirror).
int mirror(int joint) {
  switch (joint) {
    case kLeftHip:
      return kRightHip;
    case kLeftKnee:
      return kRightKnee;
    case kLeftAnkle:
      return kRightAnkle;
    case kLeftFoot:
      return kRightFoot;
    case kLeftCollar:
      return kRightCollar;
    case kLeftShoulder:
      return kRightShoulder;
    case kLeftElbow:
      return kRightElbow;
    case kLeftWrist:
      return kRightWrist;
    case kRightHip:
      return kLeftHip;
    case kRightKnee:
      return kLeftKnee;
    case kRightAnkle:
      return kLeftAnkle;
    case kRightFoot:
      return kLeftFoot;
    case kRightCollar:
      return kLeftCollar;
    case kRightShoulder:
      return kLeftShoulder;
    case kRightElbow:
      return kLeftElbow;
    case kRightWrist:
      return kLeftWrist;
    default:
      return joint;
  }
}

bool is_spine(int joint) {
  return joint == kSpine1 || joint == kSpine2 || joint == kSpine3;
}

// Joints that map_to_canonical can place from the structure when no name matches them.
bool can_infer(int joint) {
  return is_spine(joint) || joint == kLeftCollar || joint == kRightCollar || joint == kLeftFoot || joint == kRightFoot;
}

// "Hips, LHipJoint, ..." with at most `limit` names, for one-line messages.
std::string list_names(const std::vector<std::string>& names, size_t limit = 40) {
  std::string out;
  for (size_t i = 0; i < names.size() && i < limit; ++i) out += (i ? ", " : "") + names[i];
  if (names.size() > limit) out += detail::concat(", ... (", names.size() - limit, " more)");
  return out;
}

// 1-based line of the first occurrence of `needle` in `text`, or 0 when it does not occur.
int line_of(const std::string& text, const std::string& needle) {
  const size_t at = text.find(needle);
  if (at == std::string::npos) return 0;
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(at), '\n'));
}

// === Built-in conventions
//
// Written compactly: per convention, the side tokens that stand for '%' (left, right) and, per left or
// central canonical joint, the accepted names separated by '|'. Right-side names are the left ones
// with the right token. Names are given in normalize_joint_name form.

struct ConventionSpec {
  const char* name;
  std::vector<std::pair<std::string, std::string>> sides;
  std::vector<std::pair<int, std::string>> joints;
};

const std::vector<ConventionSpec>& convention_specs() {
  static const std::vector<ConventionSpec> specs = {
      {"CMU / MotionBuilder / Mixamo",
       {{"left", "right"}},
       // CMU has two neck joints; the canonical neck takes the upper one (Neck1, mid-neck, closer to
       // the canonical neck's height). Over the 20 CMU clips, the canonical neck and head then stay
       // within 2.5 to 9.6 cm of the file's (2.5 to 4.4 cm on 18 of them); with Neck, 3.2 to 8.4 cm.
       {{kPelvis, "hips"},
        {kNeck, "neck1|neck"},
        {kHead, "head"},
        {kLeftCollar, "%shoulder"},
        {kLeftShoulder, "%arm"},
        {kLeftElbow, "%forearm"},
        {kLeftWrist, "%hand"},
        {kLeftHip, "%upleg"},
        {kLeftKnee, "%leg"},
        {kLeftAnkle, "%foot"},
        {kLeftFoot, "%toebase|%toe"}}},
      {"3ds Max / Biovision",
       {{"left", "right"}},
       {{kPelvis, "hips|hip|pelvis"},
        {kNeck, "neck"},
        {kHead, "head"},
        {kLeftCollar, "%collar|%clavicle"},
        {kLeftShoulder, "%shoulder|%uparm|%upperarm"},
        {kLeftElbow, "%elbow|%lowarm|%forearm"},
        {kLeftWrist, "%wrist|%hand"},
        {kLeftHip, "%hip|%upleg|%thigh"},
        {kLeftKnee, "%knee|%lowleg|%shin"},
        {kLeftAnkle, "%ankle|%foot"},
        {kLeftFoot, "%toe|%toebase|%toes"}}},
      {"3ds Max Biped",
       {{"l", "r"}},
       {{kPelvis, "pelvis"},
        {kNeck, "neck"},
        {kHead, "head"},
        {kLeftCollar, "%clavicle"},
        {kLeftShoulder, "%upperarm"},
        {kLeftElbow, "%forearm"},
        {kLeftWrist, "%hand"},
        {kLeftHip, "%thigh"},
        {kLeftKnee, "%calf"},
        {kLeftAnkle, "%foot"},
        {kLeftFoot, "%toe0|%toe"}}},
      {"SecondLife / Poser",
       {{"l", "r"}, {"left", "right"}},
       {{kPelvis, "hip|mpelvis"},
        {kNeck, "neck|mneck"},
        {kHead, "head|mhead"},
        {kLeftCollar, "%collar|mcollar%"},
        {kLeftShoulder, "%shldr|mshoulder%"},
        {kLeftElbow, "%forearm|melbow%"},
        {kLeftWrist, "%hand|mwrist%"},
        {kLeftHip, "%thigh|mhip%"},
        {kLeftKnee, "%shin|mknee%"},
        {kLeftAnkle, "%foot|mankle%"},
        {kLeftFoot, "%toe|mfoot%"}}},
      {"SMPL",
       {{"left", "right"}, {"l", "r"}},
       {{kPelvis, "pelvis"},
        {kNeck, "neck"},
        {kHead, "head"},
        {kLeftCollar, "%collar"},
        {kLeftShoulder, "%shoulder"},
        {kLeftElbow, "%elbow"},
        {kLeftWrist, "%wrist"},
        {kLeftHip, "%hip"},
        {kLeftKnee, "%knee"},
        {kLeftAnkle, "%ankle"},
        {kLeftFoot, "%foot"}}},
      {"MMD",
       {{"左", "右"}},
       {{kPelvis, "下半身|センター"},
        {kNeck, "首"},
        {kHead, "頭"},
        {kLeftCollar, "%肩"},
        {kLeftShoulder, "%腕"},
        {kLeftElbow, "%ひじ|%肘"},
        {kLeftWrist, "%手首"},
        {kLeftHip, "%足|%脚"},
        {kLeftKnee, "%ひざ|%膝"},
        {kLeftAnkle, "%足首"},
        {kLeftFoot, "%つま先"}}},
  };
  return specs;
}

std::vector<std::string> split_alternatives(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream in(text);
  for (std::string item; std::getline(in, item, '|');) out.push_back(item);
  return out;
}

std::string replace_side(std::string pattern, const std::string& side) {
  const size_t at = pattern.find('%');
  if (at != std::string::npos) pattern.replace(at, 1, side);
  return pattern;
}

JointNameConvention expand(const ConventionSpec& spec) {
  JointNameConvention out;
  out.name = spec.name;
  for (const auto& [joint, alternatives] : spec.joints) {
    for (const std::string& pattern : split_alternatives(alternatives)) {
      if (pattern.find('%') == std::string::npos) {
        out.names[joint].push_back(pattern);
        continue;
      }
      for (const auto& [left, right] : spec.sides) {
        out.names[joint].push_back(replace_side(pattern, left));
        out.names[mirror(joint)].push_back(replace_side(pattern, right));
      }
    }
  }
  return out;
}

// === Skeleton structure

// Checks sizes, parent ranges and the absence of cycles.
void validate_hierarchy(const std::vector<std::string>& names, const std::vector<int>& parents,
                        const std::string& source) {
  const int J = static_cast<int>(names.size());
  AMT_CHECK(J > 0, source, ": skeleton: expected at least 1 joint, found none");
  AMT_CHECK(parents.size() == names.size(), source, ": joint parents: expected ", J,
            " entries (one per joint name), found ", parents.size());
  for (int j = 0; j < J; ++j) {
    AMT_CHECK(parents[j] >= -1 && parents[j] < J && parents[j] != j, source,
              ": joint parents: expected -1 or a joint in [0, ", J, ") other than itself for joint ", j, " ('",
              names[j], "'), found ", parents[j]);
  }
  // A walk up from any joint reaches a root in fewer than J steps unless there is a cycle.
  std::vector<char> reaches_root(J, 0);
  for (int j = 0; j < J; ++j) {
    std::vector<int> path;
    int k = j;
    while (k >= 0 && !reaches_root[k]) {
      path.push_back(k);
      AMT_CHECK(static_cast<int>(path.size()) <= J, source, ": joint parents: expected a tree, found a cycle through '",
                names[j], "'");
      k = parents[k];
    }
    for (int p : path) reaches_root[p] = 1;
  }
}

bool is_ancestor_or_self(int ancestor, int joint, const std::vector<int>& parents) {
  for (int k = joint; k >= 0; k = parents[k]) {
    if (k == ancestor) return true;
  }
  return false;
}

// Lowest common ancestor of a and b, or -1 when they are in different trees.
int common_ancestor(int a, int b, const std::vector<int>& parents) {
  std::unordered_set<int> above_a;
  for (int k = a; k >= 0; k = parents[k]) above_a.insert(k);
  for (int k = b; k >= 0; k = parents[k]) {
    if (above_a.count(k)) return k;
  }
  return -1;
}

// The prefix shared by every name up to and including its last separator ("Character1_"), or "" when
// there is none or when it would leave a name empty.
std::string shared_prefix(const std::vector<std::string>& names) {
  if (names.size() < 2) return "";
  std::string prefix = names[0];
  for (const std::string& name : names) {
    size_t n = 0;
    while (n < prefix.size() && n < name.size() && prefix[n] == name[n]) ++n;
    prefix.resize(n);
  }
  const size_t cut = prefix.find_last_of(":|_ .-");
  if (cut == std::string::npos) return "";
  prefix.resize(cut + 1);
  for (const std::string& name : names) {
    if (name.size() == prefix.size()) return "";
  }
  return prefix;
}

}  // namespace

// === Joint names

std::string normalize_joint_name(const std::string& name) {
  const size_t namespace_end = name.find_last_of(":|");
  const size_t start = namespace_end == std::string::npos ? 0 : namespace_end + 1;
  std::string lower;
  lower.reserve(name.size() - start);
  for (size_t i = start; i < name.size(); ++i) {
    const unsigned char c = static_cast<unsigned char>(name[i]);
    // Full-width digits U+FF10..U+FF19 are EF BC 90..99 in UTF-8.
    if (c == 0xEF && i + 2 < name.size() && static_cast<unsigned char>(name[i + 1]) == 0xBC &&
        static_cast<unsigned char>(name[i + 2]) >= 0x90 && static_cast<unsigned char>(name[i + 2]) <= 0x99) {
      lower += static_cast<char>('0' + (static_cast<unsigned char>(name[i + 2]) - 0x90));
      i += 2;
      continue;
    }
    lower += (c >= 'A' && c <= 'Z') ? static_cast<char>(c - 'A' + 'a') : static_cast<char>(c);
  }
  // 3ds Max Biped: "bip01 l thigh", "bip001_pelvis".
  if (lower.compare(0, 3, "bip") == 0) {
    size_t k = 3;
    while (k < lower.size() && lower[k] >= '0' && lower[k] <= '9') ++k;
    if (k > 3 && k < lower.size() && (lower[k] == ' ' || lower[k] == '_')) lower.erase(0, k + 1);
  }
  lower.erase(std::remove_if(lower.begin(), lower.end(), is_separator), lower.end());
  return lower;
}

const std::vector<JointNameConvention>& joint_name_conventions() {
  static const std::vector<JointNameConvention> conventions = [] {
    std::vector<JointNameConvention> out;
    for (const ConventionSpec& spec : convention_specs()) out.push_back(expand(spec));
    return out;
  }();
  return conventions;
}

// === The user's joint map

JointMapFile parse_joint_map(const std::string& json_text, const std::string& source) {
  nlohmann::ordered_json root;
  try {
    root = nlohmann::ordered_json::parse(json_text);
  } catch (const nlohmann::json::parse_error& e) {
    const size_t at = std::min(e.byte > 0 ? e.byte - 1 : 0, json_text.size());
    const int line =
        1 + static_cast<int>(std::count(json_text.begin(), json_text.begin() + static_cast<std::ptrdiff_t>(at), '\n'));
    std::string reason = e.what();
    const size_t colon = reason.find(": ");
    if (colon != std::string::npos) reason = reason.substr(colon + 2);
    fail(source, ":", line, ": joint map: expected valid JSON, found a syntax error (", reason, ")");
  }
  AMT_CHECK(root.is_object(), source,
            ":1: joint map: expected a JSON object {canonical joint: file joint}, found a JSON ", root.type_name());
  const std::vector<std::string>& canonical = canonical_joint_names();
  JointMapFile map;
  map.source = source;
  for (const auto& [key, value] : root.items()) {
    const int line = line_of(json_text, "\"" + key + "\"");
    const std::string where = line > 0 ? detail::concat(source, ":", line) : source;
    const auto found = std::find(canonical.begin(), canonical.end(), key);
    AMT_CHECK(found != canonical.end(), where, ": joint map: expected a canonical joint name (", list_names(canonical),
              "), found '", key, "'");
    AMT_CHECK(value.is_string() && !value.get<std::string>().empty(), where, ": ", key,
              ": expected the name of a joint of the file, found ",
              value.is_string() ? "an empty string" : value.dump());
    map.entries.emplace_back(static_cast<int>(found - canonical.begin()), value.get<std::string>());
  }
  return map;
}

JointMapFile read_joint_map(const std::string& path) {
  check_input_file(path, "a joint map");
  std::ifstream in(path, std::ios::binary);
  AMT_CHECK(in.good(), path, ": joint map: expected a readable file, found none");
  std::ostringstream text;
  text << in.rdbuf();
  return parse_joint_map(text.str(), path);
}

// === Mapping

std::string JointMapping::describe(const std::vector<std::string>& names) const {
  std::string out;
  for (int c = 0; c < kCanonicalJointCount; ++c) {
    const int s = source_joint[c];
    out += (c ? ", " : "") + canonical_joint_names()[c] + "=" +
           (s >= 0 && s < static_cast<int>(names.size()) ? names[s] : std::string("?"));
  }
  return out;
}

JointMapping map_to_canonical(const std::vector<std::string>& names, const std::vector<int>& parents,
                              const std::optional<JointMapFile>& user_map, const std::string& source) {
  validate_hierarchy(names, parents, source);
  const int J = static_cast<int>(names.size());
  const std::vector<std::string>& canonical = canonical_joint_names();

  JointMapping mapping;
  mapping.source_joint.fill(-1);
  std::vector<char> used(J, 0);
  const auto assign = [&](int c, int joint, JointMatchKind kind) {
    mapping.source_joint[c] = joint;
    mapping.kind[c] = kind;
    used[joint] = 1;
  };

  // Normalized names, without the prefix all of them share; the first joint wins a repeated name.
  const std::string prefix = shared_prefix(names);
  std::unordered_map<std::string, int> by_name;
  for (int j = 0; j < J; ++j) {
    const std::string key = normalize_joint_name(names[j].substr(prefix.size()));
    if (!key.empty()) by_name.emplace(key, j);
  }

  // 1. The user's map.
  if (user_map) {
    for (const auto& [c, wanted] : user_map->entries) {
      AMT_CHECK(c >= 0 && c < kCanonicalJointCount, user_map->source,
                ": joint map: expected a canonical joint index in [0, ", kCanonicalJointCount, "), found ", c);
      int joint = static_cast<int>(std::find(names.begin(), names.end(), wanted) - names.begin());
      if (joint == J) {
        const std::string key = normalize_joint_name(wanted);
        int matches = 0;
        for (int j = 0; j < J; ++j) {
          if (!key.empty() && normalize_joint_name(names[j]) == key) joint = j, ++matches;
        }
        if (matches != 1) joint = J;
      }
      AMT_CHECK(joint < J, user_map->source, ": ", canonical[c], ": expected one of the joints of ", source, " (",
                list_names(names), "), found '", wanted, "'");
      assign(c, joint, JointMatchKind::kUserMap);
    }
  }

  // 2. Name tables: the convention that matches most of the open joints, then the others for the rest.
  const std::vector<JointNameConvention>& conventions = joint_name_conventions();
  const auto lookup = [&](const JointNameConvention& convention, int c) {
    for (const std::string& name : convention.names[c]) {
      const auto found = by_name.find(name);
      if (found != by_name.end() && !used[found->second]) return found->second;
    }
    return -1;
  };
  int best = -1, best_score = 0;
  for (size_t k = 0; k < conventions.size(); ++k) {
    int score = 0;
    for (int c = 0; c < kCanonicalJointCount; ++c)
      score += mapping.source_joint[c] < 0 && lookup(conventions[k], c) >= 0;
    if (score > best_score) best = static_cast<int>(k), best_score = score;
  }
  if (best >= 0) {
    mapping.convention = conventions[best].name;
    std::vector<int> order = {best};
    for (int k = 0; k < static_cast<int>(conventions.size()); ++k) {
      if (k != best) order.push_back(k);
    }
    for (int k : order) {
      for (int c = 0; c < kCanonicalJointCount; ++c) {
        if (mapping.source_joint[c] >= 0) continue;
        const int joint = lookup(conventions[k], c);
        if (joint >= 0) assign(c, joint, JointMatchKind::kNameTable);
      }
    }
  } else {
    mapping.convention = "none";
  }

  std::vector<std::string> missing;
  for (int c = 0; c < kCanonicalJointCount; ++c) {
    if (mapping.source_joint[c] < 0 && !can_infer(c)) missing.push_back(canonical[c]);
  }
  AMT_CHECK(missing.empty(), source, ": skeleton: could not match canonical joints ", list_names(missing),
            " to any of the file's joints (", list_names(names),
            "); pass --joint-map FILE, a JSON object {canonical joint: file joint}");

  // 3. Structure.
  auto& src = mapping.source_joint;
  const auto arm_base = [&](int collar, int shoulder) { return src[collar] >= 0 ? src[collar] : src[shoulder]; };
  if (src[kSpine3] < 0) {
    int chest = common_ancestor(src[kNeck], arm_base(kLeftCollar, kLeftShoulder), parents);
    chest = chest < 0 ? -1 : common_ancestor(chest, arm_base(kRightCollar, kRightShoulder), parents);
    if (chest == src[kNeck] && parents[chest] >= 0) chest = parents[chest];
    if (chest < 0 || is_ancestor_or_self(chest, src[kPelvis], parents)) chest = src[kPelvis];
    mapping.source_joint[kSpine3] = chest;
    mapping.kind[kSpine3] = JointMatchKind::kStructure;
  }
  std::unordered_set<int> pelvis_and_above;
  for (int k = src[kPelvis]; k >= 0; k = parents[k]) pelvis_and_above.insert(k);
  std::vector<int> spine;  // from the pelvis (not included) up to spine3, root side first
  for (int k = src[kSpine3]; k >= 0 && !pelvis_and_above.count(k); k = parents[k]) spine.push_back(k);
  std::reverse(spine.begin(), spine.end());
  const auto infer = [&](int c, int joint) {
    if (src[c] >= 0) return;
    mapping.source_joint[c] = joint;
    mapping.kind[c] = JointMatchKind::kStructure;
  };
  infer(kSpine1, spine.empty() ? src[kPelvis] : spine.front());
  infer(kSpine2, spine.empty() ? src[kPelvis] : spine[(spine.size() - 1) / 2]);
  for (const auto& [collar, shoulder] :
       {std::pair{kLeftCollar, kLeftShoulder}, std::pair{kRightCollar, kRightShoulder}}) {
    infer(collar, parents[src[shoulder]] >= 0 ? parents[src[shoulder]] : src[shoulder]);
  }
  for (const auto& [foot, ankle] : {std::pair{kLeftFoot, kLeftAnkle}, std::pair{kRightFoot, kRightAnkle}}) {
    int only_child = -1, children = 0;
    for (int j = 0; j < J; ++j) {
      if (parents[j] == src[ankle]) only_child = j, ++children;
    }
    infer(foot, children == 1 ? only_child : src[ankle]);
  }

  // 4. Nonsense a user map (or an odd file) can produce is refused with the names. Structure shares
  // file joints on purpose (three spine joints on one, a foot on its ankle), and a file with fewer
  // spine joints may be mapped so by hand; any other two canonical joints on one file joint are
  // a mistake (both hips on one thigh). A canonical joint whose file joint lies strictly above its
  // canonical parent's (pelvis and head swapped) would turn the skeleton inside out.
  const auto spine_like = [](int c) { return c == kPelvis || c == kSpine1 || c == kSpine2 || c == kSpine3; };
  const std::vector<std::string>& canonical_names = canonical_joint_names();
  for (int c = 0; c < kCanonicalJointCount; ++c) {
    for (int d = 0; d < c; ++d) {
      if (src[c] != src[d] || mapping.kind[c] == JointMatchKind::kStructure ||
          mapping.kind[d] == JointMatchKind::kStructure || (spine_like(c) && spine_like(d))) {
        continue;
      }
      fail(source, ": joint map: canonical joints ", canonical_names[d], " and ", canonical_names[c],
           " are both on the file's joint ", names[src[c]], ": expected one file joint per canonical joint");
    }
  }
  const std::vector<int32_t>& canonical_parents = canonical_joint_parents();
  for (int c = 0; c < kCanonicalJointCount; ++c) {
    const int p = canonical_parents[c];
    if (p < 0 || src[c] == src[p] || !is_ancestor_or_self(src[c], src[p], parents)) continue;
    fail(source, ": joint map: canonical joint ", canonical_names[c], " is on the file's joint ", names[src[c]],
         ", which lies above ", names[src[p]], " (its parent ", canonical_names[p],
         "'s joint) in the file's skeleton: expected a joint below it");
  }
  return mapping;
}

// === Motion on the canonical skeleton

CanonicalMotion to_canonical(const Skeleton& skeleton, const Motion& motion, const JointMapping& mapping,
                             const std::string& source) {
  validate_skeleton(skeleton, source);
  validate_motion(motion, skeleton, source);
  const int J = skeleton.num_joints(), T = motion.num_frames();
  for (int c = 0; c < kCanonicalJointCount; ++c) {
    AMT_CHECK(mapping.source_joint[c] >= 0 && mapping.source_joint[c] < J, source,
              ": joint mapping: expected a joint in [0, ", J, ") for ", canonical_joint_names()[c], ", found ",
              mapping.source_joint[c]);
  }
  const auto& src = mapping.source_joint;
  const std::vector<int32_t>& canonical_parents = canonical_joint_parents();

  CanonicalMotion out;
  out.mapping = mapping;
  out.skeleton.names = canonical_joint_names();
  out.skeleton.parents = canonical_parents;
  out.skeleton.rest_joints.resize(kCanonicalJointCount, 3);
  for (int c = 0; c < kCanonicalJointCount; ++c) out.skeleton.rest_joints.row(c) = skeleton.rest_joints.row(src[c]);

  out.motion = rest_motion(out.skeleton, T, motion.fps);
  Quaternions global(J);
  std::vector<Eigen::Vector3f> position(J);
  for (int t = 0; t < T; ++t) {
    for (int j = 0; j < J; ++j) {
      const int p = skeleton.parents[j];
      const Eigen::Vector3f rest = skeleton.rest_joints.row(j).transpose();
      if (p < 0) {
        global[j] = motion.rotation(t, j);
        position[j] = rest + motion.root_translation.row(t).transpose();
      } else {
        global[j] = (global[p] * motion.rotation(t, j)).normalized();
        position[j] = position[p] + global[p] * (rest - skeleton.rest_joints.row(p).transpose());
      }
    }
    for (int c = 0; c < kCanonicalJointCount; ++c) {
      const int p = canonical_parents[c];
      out.motion.rotation(t, c) = p < 0 ? global[src[c]] : (global[src[p]].conjugate() * global[src[c]]).normalized();
    }
    out.motion.root_translation.row(t) =
        (position[src[kPelvis]] - skeleton.rest_joints.row(src[kPelvis]).transpose()).transpose();
  }
  return out;
}

}  // namespace amt
