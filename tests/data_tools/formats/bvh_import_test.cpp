// BVH import: hand-written files against positions worked out by hand (channel orders, End Sites,
// rotation-only roots, units), the 20 CMU clips (header fields, mapping, resampling, standing height,
// retargeting with the feet on the ground), and bad input (one-line errors with file and line).
#include "data_tools/formats/bvh_import.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include "data_tools/geometry/error.h"
#include "data_tools/geometry/retarget.h"

namespace amt {
namespace {

std::string asset(const std::string& name) {
  return std::string(AMT_TEST_ASSETS_DIR) + "/bvh/" + name;
}
std::string cmu(const std::string& name) {
  return std::string(AMT_ASSET_DIR) + "/mocap/cmu/" + name;
}

std::vector<std::string> cmu_files() {
  std::vector<std::string> files;
  for (const auto& entry : std::filesystem::directory_iterator(std::string(AMT_ASSET_DIR) + "/mocap/cmu")) {
    if (entry.path().extension() == ".bvh") files.push_back(entry.path().string());
  }
  std::sort(files.begin(), files.end());
  return files;
}

Eigen::Vector3f position(const Transforms& T, int j) {
  return T[j].col(3);
}

// Forward kinematics of frame t of a file at scale 1.
Transforms pose(const BvhMotion& m, int t) {
  return forward_kinematics(m.skeleton, m.motion, t);
}

// === Hand-written files

TEST(BvhParse, RawStructureOfAThreeJointChain) {
  const BvhFile f = read_bvh(asset("chain_zxy.bvh"));
  ASSERT_EQ(f.joints.size(), 3u);
  EXPECT_EQ(f.joints[0].name, "Root");
  EXPECT_EQ(f.joints[1].name, "Mid");
  EXPECT_EQ(f.joints[2].name, "Tip");
  EXPECT_EQ(f.joints[0].parent, -1);
  EXPECT_EQ(f.joints[1].parent, 0);
  EXPECT_EQ(f.joints[2].parent, 1);
  EXPECT_TRUE(f.joints[2].offset.isApprox(Eigen::Vector3d(0, 2, 0)));
  const std::vector<BvhChannel> root_channels = {BvhChannel::kXposition, BvhChannel::kYposition,
                                                 BvhChannel::kZposition, BvhChannel::kZrotation,
                                                 BvhChannel::kXrotation, BvhChannel::kYrotation};
  EXPECT_EQ(f.joints[0].channels, root_channels);
  EXPECT_EQ(f.joints[1].first_column, 6);
  EXPECT_EQ(f.joints[2].first_column, 9);
  ASSERT_EQ(f.end_sites.size(), 1u);
  EXPECT_EQ(f.end_sites[0].parent, 2);
  EXPECT_EQ(f.num_channels, 12);
  EXPECT_EQ(f.num_frames, 2);
  EXPECT_DOUBLE_EQ(f.frame_time, 0.5);
  EXPECT_DOUBLE_EQ(f.fps(), 2.0);
  EXPECT_DOUBLE_EQ(f.value(1, 2), 3.0);
  EXPECT_DOUBLE_EQ(f.value(1, 3), 90.0);
  EXPECT_DOUBLE_EQ(f.value(1, 7), 90.0);
}

TEST(BvhConvert, ChainPositionsByHand) {
  // Frame 1: the root moves to (1, 2, 3) and turns 90 degrees about Z, so the bone to Mid, (0, 1, 0)
  // at rest, points along -X: Mid at (0, 2, 3). Mid turns 90 degrees about X (channels Z X Y, only X
  // set): its bone (0, 2, 0) becomes (0, 0, 2) under Rx, which Rz keeps: Tip at (0, 2, 5). The End
  // Site bone (0, 1, 0) turns the same way: (0, 2, 6).
  const BvhMotion m = bvh_to_motion(read_bvh(asset("chain_zxy.bvh")), 1.0);
  ASSERT_EQ(m.skeleton.names, (std::vector<std::string>{"Root", "Mid", "Tip", "Tip End"}));
  EXPECT_EQ(m.skeleton.parents, (std::vector<int32_t>{-1, 0, 1, 2}));
  EXPECT_FLOAT_EQ(m.motion.fps, 2.0f);
  const Transforms rest = pose(m, 0);
  EXPECT_TRUE(position(rest, 3).isApprox(Eigen::Vector3f(0, 4, 0)));
  const Transforms T = pose(m, 1);
  EXPECT_TRUE(position(T, 0).isApprox(Eigen::Vector3f(1, 2, 3), 1e-6f));
  EXPECT_TRUE(position(T, 1).isApprox(Eigen::Vector3f(0, 2, 3), 1e-6f));
  EXPECT_TRUE(position(T, 2).isApprox(Eigen::Vector3f(0, 2, 5), 1e-6f));
  EXPECT_TRUE(position(T, 3).isApprox(Eigen::Vector3f(0, 2, 6), 1e-6f));
  EXPECT_TRUE(m.motion.root_translation.row(1).isApprox(Eigen::RowVector3f(1, 2, 3)));
  EXPECT_EQ(m.dropped_translation, 0.0);
}

TEST(BvhConvert, ChannelOrderDecidesTheRotation) {
  // The same angles, X = 90 and Z = 90, on the root; the child bone is (1, 0, 0).
  //   Xrotation Yrotation Zrotation: R = Rx Rz, Rz takes (1,0,0) to (0,1,0), Rx takes that to (0,0,1).
  //   Zrotation Xrotation Yrotation: R = Rz Rx, Rx keeps (1,0,0), Rz takes it to (0,1,0).
  const BvhMotion xyz = bvh_to_motion(read_bvh(asset("order_xyz.bvh")), 1.0);
  const BvhMotion zxy = bvh_to_motion(read_bvh(asset("order_zxy.bvh")), 1.0);
  EXPECT_TRUE(position(pose(xyz, 0), 1).isApprox(Eigen::Vector3f(0, 0, 1), 1e-6f));
  EXPECT_TRUE(position(pose(zxy, 0), 1).isApprox(Eigen::Vector3f(0, 1, 0), 1e-6f));
  // Arm has "CHANNELS 0": it keeps its rest rotation relative to the root; its End Site is 2 out.
  EXPECT_TRUE(position(pose(xyz, 0), 2).isApprox(Eigen::Vector3f(0, 0, 2), 1e-6f));
}

TEST(BvhConvert, RootWithOnlyRotations) {
  // The root has no position channels: it stays at its OFFSET (the origin). The rest figure is lifted
  // by 2 so its End Site stands on y = 0, so the root translation is a constant (0, -2, 0).
  const BvhMotion m = bvh_to_motion(read_bvh(asset("rotation_only_root.bvh")), 1.0);
  EXPECT_TRUE(m.skeleton.rest_joints.row(0).isApprox(Eigen::RowVector3f(0, 2, 0)));
  for (int t = 0; t < m.motion.num_frames(); ++t) {
    EXPECT_TRUE(m.motion.root_translation.row(t).isApprox(Eigen::RowVector3f(0, -2, 0))) << "frame " << t;
    EXPECT_TRUE(position(pose(m, t), 0).isZero(1e-6f));
  }
  // Frame 1: Yrotation 90 turns the leg about its own axis, so the knee stays below. Frame 2:
  // Zrotation -90 (order Y X Z) swings the leg sideways: Rz(-90) (0, -1, 0) = (-1, 0, 0).
  EXPECT_TRUE(position(pose(m, 1), 1).isApprox(Eigen::Vector3f(0, -1, 0), 1e-6f));
  EXPECT_TRUE(position(pose(m, 2), 1).isApprox(Eigen::Vector3f(-1, 0, 0), 1e-6f));
}

TEST(BvhConvert, EndSitesBecomeUniquelyNamedLeafJoints) {
  // "Hand" has two End Sites and a child joint already called "Hand End".
  const BvhMotion m = bvh_to_motion(read_bvh(asset("end_sites.bvh")), 1.0);
  EXPECT_EQ(m.skeleton.names,
            (std::vector<std::string>{"Hand", "Hand End", "Hand End 2", "Hand End 3", "Hand End End"}));
  EXPECT_EQ(m.skeleton.parents, (std::vector<int32_t>{-1, 0, 0, 0, 1}));
  validate_skeleton(m.skeleton, "end_sites.bvh");
  // Root Xrotation 90 (order Z Y X): the End Sites at (0,1,0) and (1,0,0) go to (0,0,1) and (1,0,0);
  // the joint at (0,0,1) goes to (0,-1,0) and its End Site to (0,-2,0).
  const Transforms T = pose(m, 0);
  EXPECT_TRUE(position(T, 2).isApprox(Eigen::Vector3f(0, 0, 1), 1e-6f));
  EXPECT_TRUE(position(T, 3).isApprox(Eigen::Vector3f(1, 0, 0), 1e-6f));
  EXPECT_TRUE(position(T, 1).isApprox(Eigen::Vector3f(0, -1, 0), 1e-6f));
  EXPECT_TRUE(position(T, 4).isApprox(Eigen::Vector3f(0, -2, 0), 1e-6f));
  EXPECT_TRUE(m.motion.rotation(0, 4).isApprox(Eigen::Quaternionf::Identity()));
}

TEST(BvhConvert, PositionChannelsOnNonRootJointsAndWindowsLineEnds) {
  // CRLF line ends; the leg has 6 channels. Frame 0 repeats its OFFSET, frame 1 moves it 0.5 down:
  // amt keeps bone lengths, so the leg stays at its OFFSET and the 0.5 (x scale 2) is reported.
  const BvhMotion m = bvh_to_motion(read_bvh(asset("crlf_joint_positions.bvh")), 2.0);
  EXPECT_NEAR(m.dropped_translation, 1.0, 1e-9);
  EXPECT_TRUE(position(pose(m, 1), 1).isApprox(Eigen::Vector3f(0, 2, 0), 1e-6f));
}

TEST(BvhConvert, ScaleMultipliesRestAndTranslation) {
  const BvhMotion m = bvh_to_motion(read_bvh(asset("chain_zxy.bvh")), 0.01);
  EXPECT_TRUE(m.skeleton.rest_joints.row(2).isApprox(Eigen::RowVector3f(0, 0.03f, 0)));
  EXPECT_TRUE(m.motion.root_translation.row(1).isApprox(Eigen::RowVector3f(0.01f, 0.02f, 0.03f)));
  EXPECT_THROW(bvh_to_motion(read_bvh(asset("chain_zxy.bvh")), 0.0), Error);
  EXPECT_THROW(bvh_to_motion(read_bvh(asset("chain_zxy.bvh")), 1e4), Error);
  BvhImportOptions options;
  options.scale = -1.0;
  EXPECT_THROW(bvh_to_canonical(read_bvh(asset("chain_zxy.bvh")), options), Error);
}

TEST(BvhConvert, HandBuiltFilesAreCheckedBeforeUse) {
  BvhFile f = read_bvh(asset("chain_zxy.bvh"));
  f.joints[2].parent = 5;
  EXPECT_THROW(bvh_to_motion(f, 1.0), Error);
  f = read_bvh(asset("chain_zxy.bvh"));
  f.values.pop_back();
  EXPECT_THROW(detect_bvh_units(f), Error);
  f = read_bvh(asset("chain_zxy.bvh"));
  f.end_sites[0].parent = -1;
  EXPECT_THROW(bvh_to_canonical(f), Error);
}

// === Units

// A vertical two-joint figure `height` units tall.
BvhFile figure_of_height(double height) {
  std::ostringstream text;
  text
      << "HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 3 Zrotation Xrotation Yrotation\n End Site\n {\n  OFFSET 0 "
      << height << " 0\n }\n}\nMOTION\nFrames: 1\nFrame Time: 0.0333333\n0 0 0\n";
  return parse_bvh(text.str(), "figure.bvh");
}

TEST(BvhUnits, DetectedFromTheRestHeight) {
  EXPECT_EQ(detect_bvh_units(figure_of_height(1.75)).name, "metres");
  EXPECT_EQ(detect_bvh_units(figure_of_height(17.0)).name, "decimetres");
  EXPECT_EQ(detect_bvh_units(figure_of_height(25.2)).name, "CMU units (1/0.45 inch)");
  EXPECT_EQ(detect_bvh_units(figure_of_height(68.0)).name, "inches");
  EXPECT_EQ(detect_bvh_units(figure_of_height(170.0)).name, "centimetres");
  EXPECT_EQ(detect_bvh_units(figure_of_height(1700.0)).name, "millimetres");
  // The documented boundaries, from either side.
  EXPECT_EQ(detect_bvh_units(figure_of_height(5.3)).name, "metres");
  EXPECT_EQ(detect_bvh_units(figure_of_height(5.5)).name, "decimetres");
  EXPECT_EQ(detect_bvh_units(figure_of_height(22.5)).name, "decimetres");
  EXPECT_EQ(detect_bvh_units(figure_of_height(22.7)).name, "CMU units (1/0.45 inch)");
  EXPECT_EQ(detect_bvh_units(figure_of_height(44.8)).name, "CMU units (1/0.45 inch)");
  EXPECT_EQ(detect_bvh_units(figure_of_height(45.0)).name, "inches");
  EXPECT_EQ(detect_bvh_units(figure_of_height(106.0)).name, "inches");
  EXPECT_EQ(detect_bvh_units(figure_of_height(108.0)).name, "centimetres");
  const BvhUnits cm = detect_bvh_units(figure_of_height(170.0));
  EXPECT_DOUBLE_EQ(cm.metres_per_unit, 0.01);
  EXPECT_DOUBLE_EQ(cm.rest_extent, 170.0);
  EXPECT_THROW(detect_bvh_units(figure_of_height(0.0)), Error);
}

TEST(BvhUnits, FrameTimesPrintedShortSnapToWholeRates) {
  BvhFile f = figure_of_height(1.7);
  f.frame_time = 0.0083333;
  EXPECT_DOUBLE_EQ(f.fps(), 120.0);
  f.frame_time = 0.0333333;
  EXPECT_DOUBLE_EQ(f.fps(), 30.0);
  f.frame_time = 0.04;
  EXPECT_DOUBLE_EQ(f.fps(), 25.0);
  f.frame_time = 0.0333;  // 30.03 fps: 0.1 % off, a rate of its own
  EXPECT_NEAR(f.fps(), 30.03003, 1e-4);
}

// === Resampling

TEST(BvhResample, FrameCountAndInterpolation) {
  // 9 frames at 120 fps: the root moves 1 cm and turns 3 degrees about Y per frame.
  Skeleton s;
  s.names = {"root"};
  s.parents = {-1};
  s.rest_joints = MatrixX3f::Zero(1, 3);
  Motion m = rest_motion(s, 9, 120.0f);
  for (int t = 0; t < 9; ++t) {
    m.rotation(t, 0) = Eigen::Quaternionf(Eigen::AngleAxisf(3.0f * t * float(M_PI) / 180, Eigen::Vector3f::UnitY()));
    m.root_translation.row(t) << 0.01f * t, 0, 0;
  }
  // To 30 fps: floor(8 * 30 / 120) + 1 = 3 frames, at source frames 0, 4, 8.
  const Motion m30 = resample_motion(m, 30.0f);
  ASSERT_EQ(m30.num_frames(), 3);
  EXPECT_FLOAT_EQ(m30.fps, 30.0f);
  EXPECT_NEAR(m30.root_translation(2, 0), 0.08f, 1e-6f);
  EXPECT_TRUE(m30.rotation(1, 0).isApprox(m.rotation(4, 0), 1e-6f));
  // To 50 fps: floor(8 * 50 / 120) + 1 = 4 frames; frame 1 is source frame 2.4, between 2 and 3.
  const Motion m50 = resample_motion(m, 50.0f);
  ASSERT_EQ(m50.num_frames(), 4);
  EXPECT_NEAR(m50.root_translation(1, 0), 0.024f, 1e-6f);
  const Eigen::AngleAxisf turn(m50.rotation(1, 0));
  EXPECT_NEAR(turn.angle() * 180 / float(M_PI), 7.2f, 1e-3f);
  EXPECT_TRUE(turn.axis().isApprox(Eigen::Vector3f::UnitY(), 1e-4f));
  // Up-sampling keeps the end points.
  const Motion m240 = resample_motion(m, 240.0f);
  ASSERT_EQ(m240.num_frames(), 17);
  EXPECT_NEAR(m240.root_translation(16, 0), 0.08f, 1e-6f);
  EXPECT_THROW(resample_motion(m, 0.0f), Error);
  EXPECT_THROW(resample_motion(m, std::nanf("")), Error);
}

// === The CMU clips

struct HeaderFields {
  int frames = 0;
  double frame_time = 0;
};

// "Frames:" and "Frame Time:" read from the text directly, independently of the parser.
HeaderFields scan_header(const std::string& path) {
  std::ifstream in(path);
  std::stringstream buffer;
  buffer << in.rdbuf();
  const std::string text = buffer.str();
  HeaderFields h;
  const size_t frames = text.find("Frames:");
  const size_t time = text.find("Frame Time:");
  if (frames != std::string::npos) h.frames = std::stoi(text.substr(frames + 7, 32));
  if (time != std::string::npos) h.frame_time = std::stod(text.substr(time + 11, 32));
  return h;
}

TEST(BvhCmu, EveryClipParsesMapsAndResamples) {
  const std::vector<std::string> files = cmu_files();
  ASSERT_EQ(files.size(), 20u);
  for (const std::string& path : files) {
    SCOPED_TRACE(path);
    const HeaderFields header = scan_header(path);
    const BvhFile f = read_bvh(path);
    EXPECT_EQ(f.num_frames, header.frames);
    EXPECT_DOUBLE_EQ(f.frame_time, header.frame_time);
    EXPECT_DOUBLE_EQ(f.fps(), 120.0);
    EXPECT_EQ(f.joints.size(), 31u);
    EXPECT_EQ(f.num_channels, 96);

    const BvhImport im = bvh_to_canonical(f);
    EXPECT_EQ(im.units.name, "CMU units (1/0.45 inch)");
    EXPECT_NEAR(im.units.metres_per_unit, 0.0564444, 1e-6);
    EXPECT_EQ(im.canonical.mapping.convention, "CMU / MotionBuilder / Mixamo");
    EXPECT_TRUE(is_canonical(im.canonical.skeleton));
    validate_skeleton(im.canonical.skeleton, path);
    validate_motion(im.canonical.motion, im.canonical.skeleton, path);
    for (int c = 0; c < kCanonicalJointCount; ++c) EXPECT_LT(im.canonical.mapping.source_joint[c], 31) << c;
    // The calibration frame dropped, then resampled from 120 to 30 fps: floor((frames - 2) * 30 / 120) + 1.
    EXPECT_TRUE(im.dropped_calibration_frame);
    EXPECT_EQ(im.canonical.motion.num_frames(), (header.frames - 2) * 30 / 120 + 1);
    EXPECT_FLOAT_EQ(im.canonical.motion.fps, 30.0f);
  }
}

TEST(BvhCmu, JointsMappedAsDocumented) {
  const BvhFile f = read_bvh(cmu("02_01.bvh"));
  BvhImportOptions options;
  options.fps = std::nullopt;
  const BvhImport im = bvh_to_canonical(f, options);
  std::vector<std::string> names;
  for (const BvhJoint& joint : f.joints) names.push_back(joint.name);
  const std::vector<std::string> expected = {
      "Hips",      "LeftUpLeg", "RightUpLeg",  "LowerBack",    "LeftLeg",  "RightLeg",     "Spine",         "LeftFoot",
      "RightFoot", "Spine1",    "LeftToeBase", "RightToeBase", "Neck1",    "LeftShoulder", "RightShoulder", "Head",
      "LeftArm",   "RightArm",  "LeftForeArm", "RightForeArm", "LeftHand", "RightHand"};
  for (int c = 0; c < kCanonicalJointCount; ++c) {
    EXPECT_EQ(names[im.canonical.mapping.source_joint[c]], expected[c]) << canonical_joint_names()[c];
  }
  EXPECT_EQ(im.canonical.motion.num_frames(), f.num_frames - 1);  // without the calibration frame
}

TEST(BvhCmu, CanonicalPosesFollowTheFullSkeleton) {
  // The canonical joints sit where their file joints are, frame after frame: exactly, except the
  // neck and head, which lose the rotation of the one CMU neck joint the canonical skeleton lacks.
  for (const std::string name : {"02_01.bvh", "05_06.bvh"}) {
    SCOPED_TRACE(name);
    const BvhFile f = read_bvh(cmu(name));
    BvhImportOptions options;
    options.fps = std::nullopt;
    options.drop_calibration_frame = false;  // frame t of both motions is frame t of the file
    const BvhImport im = bvh_to_canonical(f, options);
    const BvhMotion full = bvh_to_motion(f, im.units.metres_per_unit);
    float body = 0, neck_head = 0;
    for (int t = 0; t < f.num_frames; ++t) {
      const Transforms A = forward_kinematics(full.skeleton, full.motion, t);
      const Transforms B = forward_kinematics(im.canonical.skeleton, im.canonical.motion, t);
      for (int c = 0; c < kCanonicalJointCount; ++c) {
        const float e = (position(A, im.canonical.mapping.source_joint[c]) - position(B, c)).norm();
        float& worst = (c == kNeck || c == kHead) ? neck_head : body;
        worst = std::max(worst, e);
        // Every canonical joint turns with its file joint's global rotation.
        const Eigen::Matrix3f RA = A[im.canonical.mapping.source_joint[c]].leftCols<3>(), RB = B[c].leftCols<3>();
        ASSERT_TRUE(RA.isApprox(RB, 1e-4f)) << "frame " << t << " joint " << canonical_joint_names()[c];
      }
    }
    std::cout << "[ figures  ] " << name << ": canonical joints vs file joints, max distance " << body * 100
              << " cm (body), " << neck_head * 100 << " cm (neck, head)\n";
    EXPECT_LT(body, 1e-4f);
    EXPECT_LT(neck_head, 0.12f);
  }
}

TEST(BvhCmu, StandingHeightOfAWalk) {
  // 02_01 frame 0, a subject standing to walk. CMU's skeleton has a short torso, so the top of the
  // head (the Head End Site) is at 1.44 m while the hips are at 0.94 m, an adult's (~1.75 m tall).
  const BvhFile f = read_bvh(cmu("02_01.bvh"));
  const BvhUnits units = detect_bvh_units(f);
  const BvhMotion m = bvh_to_motion(f, units.metres_per_unit);
  const Transforms T = pose(m, 0);
  float floor = std::numeric_limits<float>::infinity();
  for (const Transform34& joint : T) floor = std::min(floor, joint(1, 3));
  const float head_top = T[m.skeleton.index_of("Head End")](1, 3) - floor;
  const float head = T[m.skeleton.index_of("Head")](1, 3) - floor;
  const float hips = T[m.skeleton.index_of("Hips")](1, 3) - floor;
  std::cout << "[ figures  ] 02_01 frame 0: scale " << units.metres_per_unit << " m/unit (" << units.name
            << ", rest extent " << units.rest_extent << " units); above the lowest point: head top " << head_top
            << " m, head joint " << head << " m, hips " << hips << " m\n";
  EXPECT_GT(head_top, 1.4f);
  EXPECT_LT(head_top, 1.9f);
  EXPECT_GT(hips, 0.85f);
  EXPECT_LT(hips, 1.05f);
}

// The canonical T-pose scaled by 0.7 with legs 1.2 times as long, standing on y = 0.
Skeleton small_long_legged_character() {
  const Skeleton base = canonical_skeleton();
  Skeleton s = base;
  const auto in_leg = [](int j) {
    return j == kLeftKnee || j == kRightKnee || j == kLeftAnkle || j == kRightAnkle || j == kLeftFoot ||
           j == kRightFoot;
  };
  s.rest_joints.row(0) = base.rest_joints.row(0) * 0.7f;
  for (int j = 1; j < s.num_joints(); ++j) {
    const int p = s.parents[j];
    Eigen::RowVector3f offset = (base.rest_joints.row(j) - base.rest_joints.row(p)) * 0.7f;
    if (in_leg(j)) offset *= 1.2f;
    s.rest_joints.row(j) = s.rest_joints.row(p) + offset;
  }
  s.rest_joints.col(1).array() -= s.rest_joints.col(1).minCoeff();
  return s;
}

// Per frame, the lowest of the ankle and foot joints (its position).
std::vector<Eigen::Vector3f> lowest_foot_joint(const Skeleton& s, const Motion& m) {
  std::vector<Eigen::Vector3f> out;
  for (int t = 0; t < m.num_frames(); ++t) {
    const Transforms T = forward_kinematics(s, m, t);
    Eigen::Vector3f low = position(T, kLeftAnkle);
    for (int j : {kRightAnkle, kLeftFoot, kRightFoot}) {
      if (T[j](1, 3) < low.y()) low = position(T, j);
    }
    out.push_back(low);
  }
  return out;
}

float spread(const std::vector<float>& values) {
  return *std::max_element(values.begin(), values.end()) - *std::min_element(values.begin(), values.end());
}

TEST(BvhCmu, RetargetedWalkKeepsTheFeetOnTheGround) {
  // The CMU capture floor is not level: over these walks towards +Z the subject's hips and feet rise
  // by about 1.7 cm per metre, so the lowest foot joint of the file itself moves up by 10 to 13 cm
  // over a clip (with a few cm of heel-to-toe roll on top). A retarget must reproduce that, scaled by
  // the leg-length ratio k, and add nothing: the test bounds the per-frame difference between the
  // retargeted character's lowest foot height and k times the file's, over the whole clip.
  const Skeleton target = small_long_legged_character();
  for (const std::string name : {"02_01.bvh", "07_01.bvh"}) {
    SCOPED_TRACE(name);
    const BvhImport im = import_bvh(cmu(name));
    const Motion retargeted = retarget_motion(im.canonical.motion, im.canonical.skeleton, target);
    const float k = leg_length(target) / leg_length(im.canonical.skeleton);
    const std::vector<Eigen::Vector3f> source = lowest_foot_joint(im.canonical.skeleton, im.canonical.motion);
    const std::vector<Eigen::Vector3f> moved = lowest_foot_joint(target, retargeted);
    std::vector<float> source_height, moved_height, difference;
    double zz = 0, zh = 0, mean_z = 0, mean_h = 0;
    for (size_t t = 0; t < source.size(); ++t) {
      source_height.push_back(source[t].y());
      moved_height.push_back(moved[t].y());
      difference.push_back(moved[t].y() - k * source[t].y());
      mean_z += source[t].z() / source.size(), mean_h += source[t].y() / source.size();
    }
    for (const Eigen::Vector3f& p : source)
      zz += (p.z() - mean_z) * (p.z() - mean_z), zh += (p.z() - mean_z) * (p.y() - mean_h);
    std::cout << "[ figures  ] " << name << " at 30 fps onto 0.7 x with legs 1.2 x (k = " << k
              << "): lowest ankle/foot joint spread " << spread(source_height) * 100 << " cm on the file's figure, "
              << spread(moved_height) * 100 << " cm retargeted (first frame " << moved_height[0] * 100
              << " cm); file floor slope " << zh / zz * 100 << " cm/m; retargeted - k x file: spread "
              << spread(difference) * 100 << " cm\n";
    EXPECT_LT(spread(difference), 0.05f);
    EXPECT_LT(spread(moved_height), k * spread(source_height) + 0.02f);
    EXPECT_LT(std::abs(moved_height[0]), 0.08f);  // the take's first frame, mid-stride
  }
}

TEST(BvhCmu, ParseTimeOfTheLargestClip) {
  // A figure for the report, not a test of speed: it never fails on time.
  const auto start = std::chrono::steady_clock::now();
  const BvhFile f = read_bvh(cmu("02_05.bvh"));
  const auto parsed = std::chrono::steady_clock::now();
  const BvhImport im = bvh_to_canonical(f);
  const auto converted = std::chrono::steady_clock::now();
  const auto ms = [](auto a, auto b) { return std::chrono::duration<double, std::milli>(b - a).count(); };
  std::cout << "[ figures  ] 02_05.bvh (" << std::filesystem::file_size(cmu("02_05.bvh")) << " bytes, " << f.num_frames
            << " frames): parse " << ms(start, parsed) << " ms, import to 30 fps canonical " << ms(parsed, converted)
            << " ms\n";
  EXPECT_TRUE(im.dropped_calibration_frame);
  EXPECT_EQ(im.canonical.motion.num_frames(), (f.num_frames - 2) / 4 + 1);
}

TEST(BvhCmu, CalibrationFramesAreDroppedSoNoJointSnaps) {
  // The CMU conversions start with a T-pose frame before the take. Without dropping it, every file's wrists or
  // feet jump 0.47 to 1.03 m between the first two frames (30 fps); a running foot moves 23 cm.
  for (const std::string& path : cmu_files()) {
    const BvhImport im = import_bvh(path);
    EXPECT_TRUE(im.dropped_calibration_frame) << path;
    const Motion& motion = im.canonical.motion;
    const Transforms T = forward_kinematics(im.canonical.skeleton, motion);
    const int J = motion.num_joints();
    float first = 0.0f;
    for (int j = 0; j < J; ++j) first = std::max(first, (T[J + j].col(3) - T[j].col(3)).norm());
    EXPECT_LT(first, 0.3f) << path << ": largest joint displacement between the first two 30 fps frames";
    BvhImportOptions keep;
    keep.drop_calibration_frame = false;
    EXPECT_EQ(import_bvh(path, keep).canonical.motion.num_frames() >= motion.num_frames(), true) << path;
  }
  // A take that starts moving at once keeps its first frame.
  Motion moving = rest_motion(canonical_skeleton(), 5);
  for (int t = 0; t < 5; ++t)
    for (int j = 0; j < moving.num_joints(); ++j)
      moving.rotation(t, j) = Eigen::Quaternionf(Eigen::AngleAxisf(0.3f + 0.01f * t, Eigen::Vector3f::UnitX()));
  EXPECT_FALSE(is_calibration_frame(moving));
  moving.rotation(0, 3) = Eigen::Quaternionf::Identity();
  for (int j = 0; j < moving.num_joints(); ++j) moving.rotation(0, j) = Eigen::Quaternionf::Identity();
  EXPECT_TRUE(is_calibration_frame(moving));
}

// === Bad input

// The message of the amt::Error that reading `name` throws ("" if none).
std::string error_of(const std::string& name) {
  try {
    read_bvh(asset(name));
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

// Checks that reading bad/<name> fails with "<path>:<rest>".
void expect_error(const std::string& name, const std::string& rest) {
  const std::string message = error_of("bad/" + name);
  EXPECT_EQ(message, asset("bad/" + name) + ":" + rest);
  EXPECT_EQ(message.find('\n'), std::string::npos);
}

TEST(BvhErrors, OneLineWithFileLineFieldExpectedAndFound) {
  // Each bad file is minimal.bvh with one defect.
  EXPECT_EQ(read_bvh(asset("minimal.bvh")).num_frames, 2);
  expect_error("empty.bvh", "1: file: expected HIERARCHY at the start of a BVH file, found end of file");
  expect_error("truncated.bvh", "9: joint 'Leg': expected JOINT, End Site or '}', found end of file");
  expect_error("missing_motion.bvh",
               "16: HIERARCHY: expected MOTION after the root joint's closing '}', found 'Frames:'");
  expect_error("too_few_frames.bvh", "20: frame 3 of 3: expected 3 frames (Frames: 3) of 9 values, found 2 frames");
  expect_error("too_many_frames.bvh",
               "21: MOTION: expected 2 frames (Frames: 2), found more data lines: '0 2 0 0 6 0 0 0 0'");
  expect_error("nan_value.bvh", "20: frame 2 of 2 (Hips Xrotation): expected a number in [-1e9, 1e9], found 'nan'");
  expect_error(
      "unknown_channel.bvh",
      "9: CHANNELS of 'Leg': expected one of Xposition, Yposition, Zposition, Xrotation, Yrotation, Zrotation, "
      "found 'Wrotation'");
  expect_error("duplicate_joint.bvh", "6: JOINT: expected a unique joint name, found 'Hips' again (first at line 2)");
  expect_error("missing_open_brace.bvh", "7: JOINT Leg: expected '{', found 'OFFSET'");
  expect_error("missing_close_brace.bvh", "15: joint 'Hips': expected JOINT, End Site or '}', found 'MOTION'");
  expect_error("short_frame_line.bvh", "20: frame 2 of 2: expected 9 values on the line, found 8");
  expect_error("bad_offset.bvh",
               "8: OFFSET of joint 'Leg': expected 3 numbers in [-1e9, 1e9], found '-1,5' as number 2");
  expect_error("zero_frame_time.bvh", "18: Frame Time: expected seconds per frame in [1e-06, 10], found '0'");
  expect_error("missing_root_name.bvh", "2: ROOT: expected a joint name on the same line, found end of line");
  expect_error("end_sight.bvh", "10: End Site of 'Leg': expected 'Site' after 'End', found 'Sight'");
}

TEST(BvhErrors, HugeFrameCountIsRejectedBeforeAllocating) {
  const std::string message = error_of("bad/huge_frames.bvh");
  EXPECT_NE(message.find("huge_frames.bvh:17: Frames: expected at most 3 frames of 9 values in the "),
            std::string::npos)
      << message;
  EXPECT_NE(message.find("bytes left in the file, found 99999999999"), std::string::npos) << message;
}

TEST(BvhErrors, MoreBadTextFromMemory) {
  const std::string good =
      "HIERARCHY\nROOT A\n{\nOFFSET 0 0 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n}\nMOTION\n"
      "Frames: 1\nFrame Time: 0.1\n1 2 3\n";
  EXPECT_NO_THROW(parse_bvh(good, "mem.bvh"));
  const auto message = [](const std::string& text) {
    try {
      parse_bvh(text, "mem.bvh");
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  const auto with = [&](const std::string& from, const std::string& to) {
    std::string text = good;
    text.replace(text.find(from), from.size(), to);
    return text;
  };
  const auto replaced = [&](const std::string& from, const std::string& to) { return message(with(from, to)); };
  EXPECT_EQ(replaced("CHANNELS 3", "CHANNELS 9"),
            "mem.bvh:5: CHANNELS of 'A': expected a channel count from 0 to 6, found '9'");
  EXPECT_EQ(replaced("Xrotation", "Zrotation"),
            "mem.bvh:5: CHANNELS of 'A': expected each channel at most once, found 'Zrotation' twice");
  EXPECT_EQ(replaced("1 2 3", "1 inf 3"),
            "mem.bvh:10: frame 1 of 1 (A Xrotation): expected a number in [-1e9, 1e9], found 'inf'");
  EXPECT_EQ(replaced("1 2 3", "1 2 3e999"),
            "mem.bvh:10: frame 1 of 1 (A Yrotation): expected a number in [-1e9, 1e9], found '3e999'");
  EXPECT_EQ(replaced("1 2 3", "1 2 -2e9"),
            "mem.bvh:10: frame 1 of 1 (A Yrotation): expected a number in [-1e9, 1e9], found '-2e9'");
  EXPECT_EQ(replaced("Frame Time: 0.1", "Frame Time: 1e-7"),
            "mem.bvh:9: Frame Time: expected seconds per frame in [1e-06, 10], found '1e-7'");
  EXPECT_EQ(replaced("1 2 3", "1 2 3 4"), "mem.bvh:10: frame 1 of 1: expected 3 values on the line, found more: '4'");
  EXPECT_EQ(replaced("Frames: 1", "Frames: -1"),
            "mem.bvh:8: Frames: expected a whole number of frames >= 1, found '-1'");
  EXPECT_EQ(replaced("Frames: 1", "Frames: 1.5"),
            "mem.bvh:8: Frames: expected a whole number of frames >= 1, found '1.5'");
  EXPECT_EQ(replaced("Frames: 1", "Frames: 99999999999999999999999"),
            "mem.bvh:8: Frames: expected a whole number of frames >= 1, found '99999999999999999999999'");
  EXPECT_EQ(replaced("Frame Time: 0.1", "Frame Time: 0.1 1 2 3"),
            "mem.bvh:9: Frame Time: expected the end of the line, found '1 2 3'");
  EXPECT_EQ(replaced("CHANNELS 3 Zrotation Xrotation Yrotation", "CHANNELS 0"),
            "mem.bvh:7: CHANNELS: expected at least one channel in the hierarchy, found none");
  EXPECT_EQ(replaced("}\nMOTION", "}\nROOT B\n{\nOFFSET 0 0 0\n}\nMOTION"),
            "mem.bvh:7: HIERARCHY: expected one ROOT (a single skeleton), found a second ROOT");
  EXPECT_EQ(replaced("ROOT A", "ROOT A\rB"),
            "mem.bvh:2: ROOT: expected a joint name of printable characters, found 'A\\x0DB'");
  EXPECT_EQ(replaced("HIERARCHY", "HIERARCHY\x01"),
            "mem.bvh:1: file: expected HIERARCHY at the start of a BVH file, found 'HIERARCHY\\x01'");
  // A UTF-8 byte order mark, "Frames :" with a space, and keywords in other cases are read.
  EXPECT_NO_THROW(parse_bvh("\xEF\xBB\xBF" + good, "mem.bvh"));
  EXPECT_EQ(parse_bvh(with("Frames: 1", "frames : 1"), "mem.bvh").num_frames, 1);
  EXPECT_EQ(parse_bvh(with("ROOT A\n{", "root A {"), "mem.bvh").joints[0].name, "A");
}

TEST(BvhErrors, UnmappableSkeletonNamesTheFile) {
  // chain_zxy.bvh has no humanoid joint names.
  try {
    import_bvh(asset("chain_zxy.bvh"));
    FAIL() << "expected amt::Error";
  } catch (const Error& e) {
    const std::string message = e.what();
    EXPECT_EQ(
        message.rfind(asset("chain_zxy.bvh") + ": skeleton: could not match canonical joints pelvis, left_hip", 0), 0u)
        << message;
    EXPECT_NE(message.find("(Root, Mid, Tip, Tip End); pass --joint-map"), std::string::npos) << message;
  }
}

}  // namespace
}  // namespace amt
