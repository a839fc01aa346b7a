// Joint-name mapping onto the canonical skeleton: every built-in convention on a synthetic skeleton
// with its names, the structural rules (spine, collars, feet), the user's JSON map and its errors,
// and the composition of rotations across joints the canonical skeleton does not have.
#include "data_tools/formats/joint_map.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <map>

#include "data_tools/geometry/error.h"

namespace amt {
namespace {

// A joint hierarchy written as (name, parent name) pairs, parents first; "" for a root.
struct Hierarchy {
  std::vector<std::string> names;
  std::vector<int> parents;

  Hierarchy& add(const std::string& name, const std::string& parent) {
    const auto found = std::find(names.begin(), names.end(), parent);
    parents.push_back(parent.empty() ? -1 : static_cast<int>(found - names.begin()));
    EXPECT_TRUE(parent.empty() || found != names.end()) << parent;
    names.push_back(name);
    return *this;
  }
};

// Adds both sides of a limb chain: pattern "%UpLeg" with side tokens, parents by the same rule.
void add_sides(Hierarchy& h, const std::vector<std::pair<std::string, std::string>>& chain, const std::string& left,
               const std::string& right) {
  for (const std::string& side : {left, right}) {
    for (const auto& [name, parent] : chain) {
      const auto fill = [&](std::string text) {
        const size_t at = text.find('%');
        if (at != std::string::npos) text.replace(at, 1, side);
        return text;
      };
      h.add(fill(name), fill(parent));
    }
  }
}

using Expected = std::map<std::string, std::string>;  // canonical joint -> file joint

// Maps `h` and checks all 22 canonical joints and the convention found.
void expect_mapping(const Hierarchy& h, const Expected& expected, const std::string& convention) {
  ASSERT_EQ(expected.size(), static_cast<size_t>(kCanonicalJointCount));
  const JointMapping m = map_to_canonical(h.names, h.parents, std::nullopt, "test.bvh");
  EXPECT_EQ(m.convention, convention);
  for (int c = 0; c < kCanonicalJointCount; ++c) {
    const std::string& name = canonical_joint_names()[c];
    ASSERT_GE(m.source_joint[c], 0) << name;
    EXPECT_EQ(h.names[m.source_joint[c]], expected.at(name)) << name;
  }
}

// Expected mapping from the 14 per-convention names: pelvis, spine1..3, neck, head, then the left
// side's collar, shoulder, elbow, wrist, hip, knee, ankle, foot as patterns with '%'.
Expected expected_from(const std::vector<std::string>& centre, const std::vector<std::string>& limbs,
                       const std::string& left, const std::string& right) {
  Expected e = {{"pelvis", centre[0]}, {"spine1", centre[1]}, {"spine2", centre[2]},
                {"spine3", centre[3]}, {"neck", centre[4]},   {"head", centre[5]}};
  const std::vector<std::string> parts = {"collar", "shoulder", "elbow", "wrist", "hip", "knee", "ankle", "foot"};
  for (size_t k = 0; k < parts.size(); ++k) {
    for (const auto& [side, token] : {std::pair{std::string("left_"), left}, std::pair{std::string("right_"), right}}) {
      std::string name = limbs[k];
      name.replace(name.find('%'), 1, token);
      e[side + parts[k]] = name;
    }
  }
  return e;
}

// === Names

TEST(JointMap, NormalizesNames) {
  EXPECT_EQ(normalize_joint_name("mixamorig:LeftUpLeg"), "leftupleg");
  EXPECT_EQ(normalize_joint_name("Bip01 L Thigh"), "lthigh");
  EXPECT_EQ(normalize_joint_name("Bip001_Pelvis"), "pelvis");
  EXPECT_EQ(normalize_joint_name("Bip01"), "bip01");
  EXPECT_EQ(normalize_joint_name("L_Hip"), "lhip");
  EXPECT_EQ(normalize_joint_name("Left Up-Leg.001"), "leftupleg001");
  EXPECT_EQ(normalize_joint_name("root|hips"), "hips");
  EXPECT_EQ(normalize_joint_name("上半身２"), "上半身2");
  EXPECT_EQ(normalize_joint_name("左つま先"), "左つま先");
  EXPECT_EQ(normalize_joint_name("___"), "");
}

TEST(JointMap, ConventionTablesCoverEveryNonSpineJoint) {
  for (const JointNameConvention& convention : joint_name_conventions()) {
    for (int c = 0; c < kCanonicalJointCount; ++c) {
      const bool spine = c == kSpine1 || c == kSpine2 || c == kSpine3;
      EXPECT_EQ(convention.names[c].empty(), spine) << convention.name << " " << canonical_joint_names()[c];
      for (const std::string& name : convention.names[c]) EXPECT_EQ(normalize_joint_name(name), name);
    }
  }
}

// === Built-in conventions

TEST(JointMap, CmuMotionBuilder) {
  Hierarchy h;
  h.add("Hips", "");
  for (const auto& [short_side, side] : {std::pair{"L", "Left"}, std::pair{"R", "Right"}}) {
    const std::string hip_joint = std::string(short_side) + "HipJoint", s = side;
    h.add(hip_joint, "Hips").add(s + "UpLeg", hip_joint).add(s + "Leg", s + "UpLeg").add(s + "Foot", s + "Leg");
    h.add(s + "ToeBase", s + "Foot").add(s + "ToeBase End", s + "ToeBase");
  }
  h.add("LowerBack", "Hips").add("Spine", "LowerBack").add("Spine1", "Spine");
  h.add("Neck", "Spine1").add("Neck1", "Neck").add("Head", "Neck1").add("Head End", "Head");
  add_sides(h,
            {{"%Shoulder", "Spine1"},
             {"%Arm", "%Shoulder"},
             {"%ForeArm", "%Arm"},
             {"%Hand", "%ForeArm"},
             {"%FingerBase", "%Hand"},
             {"%HandIndex1", "%FingerBase"}},
            "Left", "Right");
  h.add("LThumb", "LeftHand").add("RThumb", "RightHand");
  expect_mapping(
      h,
      expected_from({"Hips", "LowerBack", "Spine", "Spine1", "Neck1", "Head"},
                    {"%Shoulder", "%Arm", "%ForeArm", "%Hand", "%UpLeg", "%Leg", "%Foot", "%ToeBase"}, "Left", "Right"),
      "CMU / MotionBuilder / Mixamo");
}

Hierarchy mixamo(const std::string& prefix) {
  Hierarchy h;
  const auto p = [&](const std::string& name) { return name.empty() ? name : prefix + name; };
  h.add(p("Hips"), "").add(p("Spine"), p("Hips")).add(p("Spine1"), p("Spine")).add(p("Spine2"), p("Spine1"));
  h.add(p("Neck"), p("Spine2")).add(p("Head"), p("Neck")).add(p("HeadTop_End"), p("Head"));
  add_sides(h,
            {{p("%Shoulder"), p("Spine2")},
             {p("%Arm"), p("%Shoulder")},
             {p("%ForeArm"), p("%Arm")},
             {p("%Hand"), p("%ForeArm")},
             {p("%HandIndex1"), p("%Hand")},
             {p("%UpLeg"), p("Hips")},
             {p("%Leg"), p("%UpLeg")},
             {p("%Foot"), p("%Leg")},
             {p("%ToeBase"), p("%Foot")},
             {p("%Toe_End"), p("%ToeBase")}},
            "Left", "Right");
  return h;
}

TEST(JointMap, MixamoWithAndWithoutPrefix) {
  for (const std::string prefix : {"mixamorig:", "mixamorig1:", ""}) {
    SCOPED_TRACE(prefix);
    expect_mapping(mixamo(prefix),
                   expected_from({prefix + "Hips", prefix + "Spine", prefix + "Spine1", prefix + "Spine2",
                                  prefix + "Neck", prefix + "Head"},
                                 {prefix + "%Shoulder", prefix + "%Arm", prefix + "%ForeArm", prefix + "%Hand",
                                  prefix + "%UpLeg", prefix + "%Leg", prefix + "%Foot", prefix + "%ToeBase"},
                                 "Left", "Right"),
                   "CMU / MotionBuilder / Mixamo");
  }
}

TEST(JointMap, ThreeDsMaxStyle) {
  Hierarchy h;
  h.add("Hips", "").add("Chest", "Hips").add("Chest2", "Chest").add("Neck", "Chest2").add("Head", "Neck");
  add_sides(h,
            {{"%Collar", "Chest2"},
             {"%Shoulder", "%Collar"},
             {"%Elbow", "%Shoulder"},
             {"%Wrist", "%Elbow"},
             {"%Hip", "Hips"},
             {"%Knee", "%Hip"},
             {"%Ankle", "%Knee"},
             {"%Toe", "%Ankle"}},
            "Left", "Right");
  // Two spine joints: spine1 and spine2 share the first.
  expect_mapping(
      h,
      expected_from({"Hips", "Chest", "Chest", "Chest2", "Neck", "Head"},
                    {"%Collar", "%Shoulder", "%Elbow", "%Wrist", "%Hip", "%Knee", "%Ankle", "%Toe"}, "Left", "Right"),
      "3ds Max / Biovision");
}

TEST(JointMap, ClassicBiovisionWithoutToes) {
  Hierarchy h;
  h.add("Hips", "").add("Chest", "Hips").add("Neck", "Chest").add("Head", "Neck");
  add_sides(h,
            {{"%Collar", "Chest"},
             {"%UpArm", "%Collar"},
             {"%LowArm", "%UpArm"},
             {"%Hand", "%LowArm"},
             {"%UpLeg", "Hips"},
             {"%LowLeg", "%UpLeg"},
             {"%Foot", "%LowLeg"},
             {"%Foot End", "%Foot"}},
            "Left", "Right");
  // One spine joint takes all three; the foot without a toe joint ends at its End Site.
  expect_mapping(h,
                 expected_from({"Hips", "Chest", "Chest", "Chest", "Neck", "Head"},
                               {"%Collar", "%UpArm", "%LowArm", "%Hand", "%UpLeg", "%LowLeg", "%Foot", "%Foot End"},
                               "Left", "Right"),
                 "3ds Max / Biovision");
}

TEST(JointMap, ThreeDsMaxBiped) {
  Hierarchy h;
  h.add("Bip01", "").add("Bip01 Pelvis", "Bip01").add("Bip01 Spine", "Bip01 Pelvis");
  h.add("Bip01 Spine1", "Bip01 Spine").add("Bip01 Spine2", "Bip01 Spine1").add("Bip01 Neck", "Bip01 Spine2");
  h.add("Bip01 Head", "Bip01 Neck");
  // Biped hangs the clavicles on the neck and (in older rigs) the thighs on the first spine joint.
  add_sides(h,
            {{"Bip01 % Clavicle", "Bip01 Neck"},
             {"Bip01 % UpperArm", "Bip01 % Clavicle"},
             {"Bip01 % Forearm", "Bip01 % UpperArm"},
             {"Bip01 % Hand", "Bip01 % Forearm"},
             {"Bip01 % Thigh", "Bip01 Spine"},
             {"Bip01 % Calf", "Bip01 % Thigh"},
             {"Bip01 % Foot", "Bip01 % Calf"},
             {"Bip01 % Toe0", "Bip01 % Foot"}},
            "L", "R");
  expect_mapping(
      h,
      expected_from({"Bip01 Pelvis", "Bip01 Spine", "Bip01 Spine1", "Bip01 Spine2", "Bip01 Neck", "Bip01 Head"},
                    {"Bip01 % Clavicle", "Bip01 % UpperArm", "Bip01 % Forearm", "Bip01 % Hand", "Bip01 % Thigh",
                     "Bip01 % Calf", "Bip01 % Foot", "Bip01 % Toe0"},
                    "L", "R"),
      "3ds Max Biped");
}

Hierarchy second_life(bool end_sites) {
  Hierarchy h;
  h.add("hip", "").add("abdomen", "hip").add("chest", "abdomen").add("neck", "chest").add("head", "neck");
  add_sides(h,
            {{"%Collar", "chest"},
             {"%Shldr", "%Collar"},
             {"%ForeArm", "%Shldr"},
             {"%Hand", "%ForeArm"},
             {"%Thigh", "hip"},
             {"%Shin", "%Thigh"},
             {"%Foot", "%Shin"}},
            "l", "r");
  if (end_sites) h.add("lFoot End", "lFoot").add("rFoot End", "rFoot");
  return h;
}

TEST(JointMap, SecondLifePoser) {
  const std::vector<std::string> centre = {"hip", "abdomen", "abdomen", "chest", "neck", "head"};
  expect_mapping(
      second_life(true),
      expected_from(centre, {"%Collar", "%Shldr", "%ForeArm", "%Hand", "%Thigh", "%Shin", "%Foot", "%Foot End"}, "l",
                    "r"),
      "SecondLife / Poser");
  // Without End Site joints the foot is the ankle itself.
  expect_mapping(
      second_life(false),
      expected_from(centre, {"%Collar", "%Shldr", "%ForeArm", "%Hand", "%Thigh", "%Shin", "%Foot", "%Foot"}, "l", "r"),
      "SecondLife / Poser");
}

TEST(JointMap, SmplNames) {
  const Hierarchy canonical{canonical_joint_names(), canonical_joint_parents()};
  Expected identity;
  for (const std::string& name : canonical_joint_names()) identity[name] = name;
  expect_mapping(canonical, identity, "SMPL");

  // "L_Hip" style, behind a prefix every name shares (SMPL's FBX export: "m_avg_L_Hip").
  Hierarchy capitals = canonical;
  for (std::string& name : capitals.names) {
    std::string renamed = name;
    if (renamed.rfind("left_", 0) == 0) renamed = "L_" + renamed.substr(5);
    if (renamed.rfind("right_", 0) == 0) renamed = "R_" + renamed.substr(6);
    renamed[renamed.find_first_not_of("LR_")] =
        static_cast<char>(std::toupper(renamed[renamed.find_first_not_of("LR_")]));
    name = "m_avg_" + renamed;
  }
  Expected renamed;
  for (int c = 0; c < kCanonicalJointCount; ++c) renamed[canonical_joint_names()[c]] = capitals.names[c];
  EXPECT_EQ(renamed.at("left_foot"), "m_avg_L_Foot");
  expect_mapping(capitals, renamed, "SMPL");
}

TEST(JointMap, MmdJapaneseBoneNames) {
  Hierarchy h;
  h.add("全ての親", "").add("センター", "全ての親").add("上半身", "センター").add("上半身2", "上半身");
  h.add("首", "上半身2").add("頭", "首").add("下半身", "センター");
  add_sides(h,
            {{"%肩", "上半身2"},
             {"%腕", "%肩"},
             {"%ひじ", "%腕"},
             {"%手首", "%ひじ"},
             {"%足", "下半身"},
             {"%ひざ", "%足"},
             {"%足首", "%ひざ"},
             {"%つま先", "%足首"},
             {"%足ＩＫ", "全ての親"}},
            "左", "右");
  // The spine rises from センター, beside 下半身: spine1 and spine2 share 上半身.
  expect_mapping(h,
                 expected_from({"下半身", "上半身", "上半身", "上半身2", "首", "頭"},
                               {"%肩", "%腕", "%ひじ", "%手首", "%足", "%ひざ", "%足首", "%つま先"}, "左", "右"),
                 "MMD");
}

TEST(JointMap, HowEachJointWasFound) {
  const Hierarchy canonical{canonical_joint_names(), canonical_joint_parents()};
  const JointMapping m = map_to_canonical(canonical.names, canonical.parents, std::nullopt, "smpl");
  for (int c = 0; c < kCanonicalJointCount; ++c) {
    const bool structural = c == kSpine1 || c == kSpine2 || c == kSpine3;
    EXPECT_EQ(m.kind[c], structural ? JointMatchKind::kStructure : JointMatchKind::kNameTable) << c;
  }
  EXPECT_EQ(m.describe(canonical.names).substr(0, 34), "pelvis=pelvis, left_hip=left_hip, ");
}

TEST(JointMap, LongerSpinePicksFirstMiddleAndLast) {
  // Five spine joints: spine1 = the first, spine2 = the ((5 - 1) / 2) = 2nd from 0, spine3 = the last.
  Hierarchy h = mixamo("");
  Hierarchy longer;
  for (size_t j = 0; j < h.names.size(); ++j) {
    const std::string parent = h.parents[j] < 0 ? "" : h.names[h.parents[j]];
    if (h.names[j] == "Neck") longer.add("Spine3", "Spine2").add("Spine4", "Spine3");
    const bool on_chest = parent == "Spine2" && h.names[j] != "Spine2";
    longer.add(h.names[j], on_chest ? "Spine4" : parent);
  }
  const JointMapping m = map_to_canonical(longer.names, longer.parents, std::nullopt, "long.bvh");
  EXPECT_EQ(longer.names[m.source_joint[kSpine1]], "Spine");
  EXPECT_EQ(longer.names[m.source_joint[kSpine2]], "Spine2");
  EXPECT_EQ(longer.names[m.source_joint[kSpine3]], "Spine4");
}

// === The user's map

TEST(JointMap, UserMapOverridesTheTables) {
  const Hierarchy h = mixamo("");
  const JointMapFile user =
      parse_joint_map(R"({"left_wrist": "LeftHandIndex1", "spine3": "Spine1", "pelvis": "HIPS"})", "map.json");
  ASSERT_EQ(user.entries.size(), 3u);
  EXPECT_EQ(user.entries[0], (std::pair<int, std::string>{kLeftWrist, "LeftHandIndex1"}));
  const JointMapping m = map_to_canonical(h.names, h.parents, user, "walk.bvh");
  EXPECT_EQ(h.names[m.source_joint[kLeftWrist]], "LeftHandIndex1");
  EXPECT_EQ(m.kind[kLeftWrist], JointMatchKind::kUserMap);
  EXPECT_EQ(h.names[m.source_joint[kRightWrist]], "RightHand");
  EXPECT_EQ(m.kind[kRightWrist], JointMatchKind::kNameTable);
  EXPECT_EQ(h.names[m.source_joint[kPelvis]], "Hips");  // by normalized name
  EXPECT_EQ(h.names[m.source_joint[kSpine3]], "Spine1");
  // The spine below the user's spine3: Spine, Spine1.
  EXPECT_EQ(h.names[m.source_joint[kSpine1]], "Spine");
  EXPECT_EQ(h.names[m.source_joint[kSpine2]], "Spine");
  // "Head" is taken by the user's neck, so the tables leave the head unmatched.
  try {
    map_to_canonical(h.names, h.parents, parse_joint_map(R"({"neck": "Head"})", "map.json"), "walk.bvh");
    FAIL() << "expected amt::Error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind("walk.bvh: skeleton: could not match canonical joints head to any", 0), 0u)
        << e.what();
  }
}

TEST(JointMap, ContradictoryUserMapsAreRefusedWithTheNames) {
  const Hierarchy h = mixamo("");
  const auto error = [&](const std::string& json) {
    try {
      map_to_canonical(h.names, h.parents, parse_joint_map(json, "map.json"), "walk.bvh");
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(error(R"({"left_hip": "LeftUpLeg", "right_hip": "LeftUpLeg"})"),
            "walk.bvh: joint map: canonical joints left_hip and right_hip are both on the file's joint LeftUpLeg: "
            "expected one file joint per canonical joint");
  EXPECT_EQ(error(R"({"pelvis": "Head", "head": "Hips"})"),
            "walk.bvh: joint map: canonical joint neck is on the file's joint Neck, which lies above Head (its "
            "parent spine3's joint) in the file's skeleton: expected a joint below it");
  // Two spine joints on one file joint is how a short spine is mapped by hand: accepted.
  EXPECT_EQ(error(R"({"spine1": "Spine", "spine2": "Spine"})"), "no error");
}

TEST(JointMap, UnknownSkeletonMapsWithAUserMap) {
  Hierarchy robot;
  robot.add("base", "").add("torso", "base").add("cap", "torso").add("dome", "cap");
  add_sides(robot,
            {{"arm%1", "torso"},
             {"arm%2", "arm%1"},
             {"arm%3", "arm%2"},
             {"leg%1", "base"},
             {"leg%2", "leg%1"},
             {"leg%3", "leg%2"}},
            "L", "R");
  const char* json = R"({"pelvis": "base", "neck": "cap", "head": "dome",
    "left_shoulder": "armL1", "left_elbow": "armL2", "left_wrist": "armL3",
    "right_shoulder": "armR1", "right_elbow": "armR2", "right_wrist": "armR3",
    "left_hip": "legL1", "left_knee": "legL2", "left_ankle": "legL3",
    "right_hip": "legR1", "right_knee": "legR2", "right_ankle": "legR3"})";
  const JointMapping m = map_to_canonical(robot.names, robot.parents, parse_joint_map(json, "robot.json"), "robot.bvh");
  EXPECT_EQ(m.convention, "none");
  // The rest from the structure: the torso is the only spine joint, and carries the arms (collars).
  for (int c : {kSpine1, kSpine2, kSpine3, kLeftCollar, kRightCollar})
    EXPECT_EQ(robot.names[m.source_joint[c]], "torso");
  EXPECT_EQ(robot.names[m.source_joint[kLeftFoot]], "legL3");
}

TEST(JointMap, UnknownSkeletonListsWhatCouldNotBeMatched) {
  const std::vector<std::string> names = {"a", "b", "c"};
  try {
    map_to_canonical(names, {-1, 0, 1}, std::nullopt, "x.bvh");
    FAIL() << "expected amt::Error";
  } catch (const Error& e) {
    EXPECT_EQ(
        std::string(e.what()),
        "x.bvh: skeleton: could not match canonical joints pelvis, left_hip, right_hip, left_knee, right_knee, "
        "left_ankle, right_ankle, neck, head, left_shoulder, right_shoulder, left_elbow, right_elbow, left_wrist, "
        "right_wrist to any of the file's joints (a, b, c); pass --joint-map FILE, a JSON object {canonical "
        "joint: file joint}");
  }
  // One joint renamed: only it is listed.
  Hierarchy h = mixamo("mixamorig:");
  h.names[std::find(h.names.begin(), h.names.end(), "mixamorig:Head") - h.names.begin()] = "mixamorig:Skull";
  try {
    map_to_canonical(h.names, h.parents, std::nullopt, "y.bvh");
    FAIL() << "expected amt::Error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind("y.bvh: skeleton: could not match canonical joints head to any of the "
                                          "file's joints (mixamorig:Hips, mixamorig:Spine, ",
                                          0),
              0u)
        << e.what();
  }
}

std::string joint_map_error(const std::string& json) {
  try {
    parse_joint_map(json, "map.json");
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(JointMap, BadUserMaps) {
  const std::string malformed = joint_map_error("{\n  \"pelvis\": \"Hips\",\n  \"neck\": \n}");
  EXPECT_EQ(malformed.rfind("map.json:4: joint map: expected valid JSON, found a syntax error (", 0), 0u) << malformed;
  EXPECT_EQ(malformed.find('\n'), std::string::npos);
  EXPECT_EQ(joint_map_error("{\n  \"pelvis\": \"Hips\",\n  \"hips\": \"Hips\"\n}"),
            "map.json:3: joint map: expected a canonical joint name (pelvis, left_hip, right_hip, spine1, left_knee, "
            "right_knee, spine2, left_ankle, right_ankle, spine3, left_foot, right_foot, neck, left_collar, "
            "right_collar, head, left_shoulder, right_shoulder, left_elbow, right_elbow, left_wrist, right_wrist), "
            "found 'hips'");
  EXPECT_EQ(joint_map_error(R"({"pelvis": 3})"),
            "map.json:1: pelvis: expected the name of a joint of the file, found 3");
  EXPECT_EQ(joint_map_error(R"({"pelvis": ""})"),
            "map.json:1: pelvis: expected the name of a joint of the file, found an empty string");
  EXPECT_EQ(joint_map_error(R"(["pelvis"])"),
            "map.json:1: joint map: expected a JSON object {canonical joint: file joint}, found a JSON array");
  EXPECT_THROW(read_joint_map("/nonexistent/map.json"), Error);

  // A name that is not in the file.
  const Hierarchy h = mixamo("");
  try {
    map_to_canonical(h.names, h.parents, parse_joint_map(R"({"left_hip": "LThigh"})", "map.json"), "walk.bvh");
    FAIL() << "expected amt::Error";
  } catch (const Error& e) {
    EXPECT_EQ(
        std::string(e.what()).rfind("map.json: left_hip: expected one of the joints of walk.bvh (Hips, Spine, ", 0), 0u)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("), found 'LThigh'"), std::string::npos) << e.what();
  }
}

TEST(JointMap, BadHierarchies) {
  EXPECT_THROW(map_to_canonical({"a", "b"}, {-1}, std::nullopt, "x"), Error);
  EXPECT_THROW(map_to_canonical({"a", "b"}, {-1, 5}, std::nullopt, "x"), Error);
  EXPECT_THROW(map_to_canonical({"a", "b", "c"}, {-1, 2, 1}, std::nullopt, "x"), Error);  // b <-> c cycle
  EXPECT_THROW(map_to_canonical({}, {}, std::nullopt, "x"), Error);
}

// === Composition onto the canonical skeleton

Eigen::Quaternionf about(const Eigen::Vector3f& axis, float degrees) {
  return Eigen::Quaternionf(Eigen::AngleAxisf(degrees * float(M_PI) / 180, axis));
}

TEST(JointMap, ToCanonicalComposesRotationsOfSkippedJoints) {
  // The canonical skeleton with a "hip_twist" joint between the pelvis and the left hip.
  const Skeleton canonical = canonical_skeleton();
  Skeleton full;
  for (int c = 0; c < kCanonicalJointCount; ++c) {
    if (c == kLeftHip) {
      full.names.push_back("hip_twist");
      full.parents.push_back(0);
    }
    full.names.push_back(canonical.names[c]);
    const int p = canonical.parents[c];
    full.parents.push_back(p < 0 ? -1 : full.index_of(canonical.names[p]));
  }
  full.parents[full.index_of("left_hip")] = full.index_of("hip_twist");
  full.rest_joints.resize(full.num_joints(), 3);
  for (int j = 0; j < full.num_joints(); ++j) {
    const int c = canonical.index_of(full.names[j]);
    full.rest_joints.row(j) = c >= 0 ? canonical.rest_joints.row(c) : Eigen::RowVector3f(0.05f, 0.9f, 0.0f);
  }
  validate_skeleton(full, "full");

  Motion motion = rest_motion(full, 2);
  motion.rotation(1, full.index_of("pelvis")) = about(Eigen::Vector3f::UnitZ(), 10);
  motion.rotation(1, full.index_of("hip_twist")) = about(Eigen::Vector3f::UnitX(), 30);
  motion.rotation(1, full.index_of("left_hip")) = about(Eigen::Vector3f::UnitX(), 20);
  motion.rotation(1, full.index_of("left_knee")) = about(Eigen::Vector3f::UnitX(), -40);
  motion.root_translation.row(1) << 0.1f, 0.0f, 0.2f;

  const JointMapping mapping = map_to_canonical(full.names, full.parents, std::nullopt, "full");
  const CanonicalMotion out = to_canonical(full, motion, mapping, "full");
  EXPECT_TRUE(is_canonical(out.skeleton));
  EXPECT_TRUE(out.skeleton.rest_joints.isApprox(canonical.rest_joints));
  // The twist passes its 30 degrees on to the canonical left hip: 30 + 20 about X.
  EXPECT_TRUE(out.motion.rotation(1, kLeftHip).isApprox(about(Eigen::Vector3f::UnitX(), 50), 1e-6f));
  EXPECT_TRUE(out.motion.rotation(1, kPelvis).isApprox(about(Eigen::Vector3f::UnitZ(), 10), 1e-6f));
  EXPECT_TRUE(out.motion.rotation(1, kLeftKnee).isApprox(about(Eigen::Vector3f::UnitX(), -40), 1e-6f));
  EXPECT_TRUE(out.motion.rotation(0, kLeftHip).isApprox(Eigen::Quaternionf::Identity()));
  EXPECT_TRUE(out.motion.root_translation.row(1).isApprox(Eigen::RowVector3f(0.1f, 0.0f, 0.2f)));
  // Global rotations agree joint by joint.
  const Transforms A = forward_kinematics(full, motion, 1), B = forward_kinematics(out.skeleton, out.motion, 1);
  for (int c = 0; c < kCanonicalJointCount; ++c) {
    EXPECT_TRUE(A[mapping.source_joint[c]].leftCols<3>().isApprox(B[c].leftCols<3>(), 1e-5f)) << c;
  }
}

}  // namespace
}  // namespace amt
