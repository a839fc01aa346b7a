#include "data_tools/builder/body_generator.h"

#include <openvdb/openvdb.h>
#include <openvdb/tools/SignedFloodFill.h>
#include <openvdb/tools/VolumeToMesh.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <mutex>
#include <string>

#include "data_tools/geometry/error.h"

namespace amt {

namespace {

using Eigen::Matrix3f;
using Eigen::Vector3f;

constexpr float kDegrees = 3.14159265358979f / 180.0f;

// === Random draws from raw engine output (std::uniform_real_distribution differs between libraries)

// Uniform in [0, 1) from the top 24 bits of one 32-bit draw.
float uniform01(std::mt19937& rng) {
  return static_cast<float>(rng() >> 8) * (1.0f / 16777216.0f);
}

float uniform(std::mt19937& rng, float lo, float hi) {
  return lo + (hi - lo) * uniform01(rng);
}

float lerp(float a, float b, float t) {
  return a + (b - a) * t;
}

// === Shapes

// A tapered capsule ("round cone": two spheres and the cone tangent to both) in a squashed space.
// value(p) = k * round_cone(center + A (p - center)): A maps the world around `center` into the cone's
// space (identity for a plain capsule) and k = 1 / |A|_2 keeps the value a lower bound of the distance
// with Lipschitz constant 1, which the block culling of the mesher relies on. A sphere has a == b.
struct Part {
  Vector3f a = Vector3f::Zero(), b = Vector3f::Zero();  // axis ends in the cone's space, metres
  float ra = 0, rb = 0;                                 // radii at a and b
  Matrix3f A = Matrix3f::Identity();
  Vector3f center = Vector3f::Zero();
  float k = 1;
  int joint = 0;         // canonical joint whose skinning weight the part carries
  bool surface = true;   // contributes to the body surface
  bool skinning = true;  // contributes to the skinning weights

  // Derived by prepare().
  Vector3f ba = Vector3f::Zero();
  float l2 = 0, rr = 0, a2 = 0, il2 = 0;
  bool squashed = false, degenerate = false;

  void prepare() {
    ba = b - a;
    l2 = ba.squaredNorm();
    rr = ra - rb;
    a2 = l2 - rr * rr;
    degenerate = a2 <= 1e-12f;  // one sphere inside the other (or a sphere): the larger sphere
    il2 = degenerate ? 0.0f : 1.0f / l2;
    squashed = !A.isIdentity();
  }

  Vector3f to_cone_space(const Vector3f& p) const { return squashed ? Vector3f(center + A * (p - center)) : p; }

  // Signed distance bound (metres): negative inside.
  float value(const Vector3f& p) const {
    const Vector3f q = to_cone_space(p);
    float d;
    if (degenerate) {
      d = ra >= rb ? (q - a).norm() - ra : (q - b).norm() - rb;
    } else {
      // Inigo Quilez, "Round cone - exact" (iquilezles.org/articles/distfunctions), one square root.
      const Vector3f pa = q - a;
      const float y = pa.dot(ba);
      const float z = y - l2;
      const float x2 = (pa * l2 - ba * y).squaredNorm();
      const float y2 = y * y * l2;
      const float z2 = z * z * l2;
      const float kk = (rr > 0 ? 1.0f : (rr < 0 ? -1.0f : 0.0f)) * rr * rr * x2;
      const float sz = z > 0 ? 1.0f : (z < 0 ? -1.0f : 0.0f);
      const float sy = y > 0 ? 1.0f : (y < 0 ? -1.0f : 0.0f);
      if (sz * a2 * z2 > kk) {
        d = std::sqrt(x2 + z2) * il2 - rb;
      } else if (sy * a2 * y2 < kk) {
        d = std::sqrt(x2 + y2) * il2 - ra;
      } else {
        d = (std::sqrt(x2 * a2 * il2) + y * rr) * il2 - ra;
      }
    }
    return k * d;
  }

  // World-space radius (metres, lower bound when squashed) of the part at p's projection on the axis.
  float radius_near(const Vector3f& p) const {
    if (degenerate) return k * std::max(ra, rb);
    const float t = std::clamp((to_cone_space(p) - a).dot(ba) / l2, 0.0f, 1.0f);
    return k * (ra + t * (rb - ra));
  }

  // World-space axis-aligned bounds.
  Eigen::AlignedBox3f bounds() const {
    const Vector3f lo = (a.array() - ra).min(b.array() - rb).matrix();
    const Vector3f hi = (a.array() + ra).max(b.array() + rb).matrix();
    if (!squashed) return Eigen::AlignedBox3f(lo, hi);
    const Matrix3f A_inv = A.inverse();
    Eigen::AlignedBox3f box;
    for (int corner = 0; corner < 8; ++corner) {
      const Vector3f q((corner & 1) ? hi.x() : lo.x(), (corner & 2) ? hi.y() : lo.y(), (corner & 4) ? hi.z() : lo.z());
      box.extend(Vector3f(center + A_inv * (q - center)));
    }
    return box;
  }
};

// A matrix that squashes space by `factor` (< 1 flattens) along the unit direction n, and its k.
void squash_along(Part& part, const Vector3f& n, float factor, const Vector3f& center) {
  part.A = Matrix3f::Identity() + (1.0f / factor - 1.0f) * n * n.transpose();
  part.center = center;
  part.k = std::min(1.0f, factor);
}

Part make_part(int joint, const Vector3f& a, const Vector3f& b, float ra, float rb, bool surface, bool skinning) {
  Part p;
  p.joint = joint;
  p.a = a;
  p.b = b;
  p.ra = ra;
  p.rb = rb;
  p.surface = surface;
  p.skinning = skinning;
  return p;
}

// Smooth union of the parts' values d_i at one point: m - (k/4) sum_{i != argmin} h_i^2 with
// h_i = max(0, 1 - (d_i - m) / k), m = min_i d_i. For two parts this is the quadratic polynomial
// smooth minimum (Quilez, "Smooth minimum"); for more it is symmetric in the parts and exact under
// culling: a part farther than k above the minimum contributes nothing.
float smooth_union(const float* d, int count, float blend) {
  float m = std::numeric_limits<float>::infinity();
  int arg = -1;
  for (int i = 0; i < count; ++i) {
    if (d[i] < m) {
      m = d[i];
      arg = i;
    }
  }
  float bump = 0;
  for (int i = 0; i < count; ++i) {
    if (i == arg) continue;
    const float h = 1.0f - (d[i] - m) / blend;
    if (h > 0) bump += h * h;
  }
  return m - 0.25f * blend * bump;
}

// === Layout: skeleton and parts from the parameters

struct Layout {
  Skeleton skeleton;
  std::vector<Part> parts;
  float blend = 0;  // smooth-union width, metres
};

Layout body_layout(const BodyParams& p) {
  validate_body_params(p);
  const float H = p.height;
  const float head = p.head_ratio * H;
  const float y_chin = H - head;
  const float neck_len = p.neck_ratio * H;
  const float y_sh = y_chin - neck_len;    // shoulder joints
  const float y_hip = p.leg_ratio * y_sh;  // hip joints
  const float torso = y_sh - y_hip;
  const float limb = p.limb_thickness * H;  // unit of limb radii
  // Foot radii, and the ankle low enough for the shin's end to reach into the (squashed) foot.
  const float foot_squash = 0.65f, r_heel = 0.026f * limb, r_toe = 0.019f * limb;
  const float r_ankle_free = 0.021f * limb;
  const float ankle_h = std::min({0.045f * H, 0.15f * y_hip, 2 * foot_squash * r_heel + 0.5f * r_ankle_free});
  const float y_knee = ankle_h + 0.52f * (y_hip - ankle_h);
  const float xh = 0.5f * p.hip_width * H;
  const float xs = 0.5f * p.shoulder_width * H;
  const float arm = p.arm_ratio * H;
  const float angle = p.arm_angle_deg * kDegrees;

  // Joints (left side; the right side mirrors x).
  const float y_pelvis = y_hip + 0.13f * torso, y_spine1 = y_hip + 0.33f * torso;
  const float y_spine2 = y_hip + 0.57f * torso, y_spine3 = y_hip + 0.68f * torso;
  const Vector3f pelvis(0, y_pelvis, 0), spine1(0, y_spine1, -0.005f * H), spine2(0, y_spine2, -0.005f * H),
      spine3(0, y_spine3, 0), neck(0, y_sh + 0.6f * neck_len, -0.005f * H),
      head_joint(0, y_chin + 0.43f * head, 0.01f * H);
  const Vector3f hip(xh, y_hip, 0), knee(1.08f * xh, y_knee, 0.005f * H), ankle(1.08f * xh, ankle_h, -0.02f * H);
  const Vector3f collar(0.38f * xs, y_sh - 0.055f * torso, -0.005f * H), shoulder(xs, y_sh, -0.01f * H);
  const Vector3f arm_dir(std::cos(angle), -std::sin(angle), 0);
  const Vector3f elbow = shoulder + 0.5f * arm * arm_dir, wrist = elbow + 0.5f * arm * arm_dir;

  // Foot: a capsule from heel to toe lying on the ground, squashed vertically about y = 0; its centre
  // line (cone space y = radius) sits at squash * radius in the world. The foot joint is the ball.
  const float foot_len = 0.15f * H;
  const float z_back = ankle.z() - 0.035f * H;
  const float z_heel = z_back + r_heel, z_toe = std::max(z_back + foot_len - r_toe, z_heel + 0.02f * H);
  const float ball_t = std::clamp((z_back + 0.72f * foot_len - z_heel) / (z_toe - z_heel), 0.3f, 0.9f);
  const float z_ball = lerp(z_heel, z_toe, ball_t);
  const float r_ball = lerp(r_heel, r_toe, ball_t);
  const float x_foot = 1.15f * xh;
  const Vector3f foot(x_foot, foot_squash * r_ball, z_ball);

  Layout out;
  out.blend = 0.012f * H;
  Skeleton& s = out.skeleton;
  s.names = canonical_joint_names();
  s.parents = canonical_joint_parents();
  s.rest_joints.resize(kCanonicalJointCount, 3);
  const Vector3f mirror(-1, 1, 1);
  auto set_pair = [&](int left, int right, const Vector3f& q) {
    s.rest_joints.row(left) = q.transpose();
    s.rest_joints.row(right) = q.cwiseProduct(mirror).transpose();
  };
  s.rest_joints.row(kPelvis) = pelvis.transpose();
  s.rest_joints.row(kSpine1) = spine1.transpose();
  s.rest_joints.row(kSpine2) = spine2.transpose();
  s.rest_joints.row(kSpine3) = spine3.transpose();
  s.rest_joints.row(kNeck) = neck.transpose();
  s.rest_joints.row(kHead) = head_joint.transpose();
  set_pair(kLeftHip, kRightHip, hip);
  set_pair(kLeftKnee, kRightKnee, knee);
  set_pair(kLeftAnkle, kRightAnkle, ankle);
  set_pair(kLeftFoot, kRightFoot, foot);
  set_pair(kLeftCollar, kRightCollar, collar);
  set_pair(kLeftShoulder, kRightShoulder, shoulder);
  set_pair(kLeftElbow, kRightElbow, elbow);
  set_pair(kLeftWrist, kRightWrist, wrist);

  std::vector<Part>& parts = out.parts;
  const Vector3f z_axis(0, 0, 1), y_axis(0, 1, 0);

  // Torso: two surface cones hip -> waist -> chest (squashed front to back about the spine), and a
  // chain of skinning cones along the spine with radii interpolated on the same profile.
  const float r_hip = p.hip_radius * H, r_waist = p.waist_radius * H, r_chest = p.chest_radius * H;
  // The lower torso's sphere ends 0.05 H below the hip joints (the crotch), the upper one 0.02 H above
  // the shoulder joints.
  const float y_bottom = std::min(y_hip - 0.05f * H + r_hip, y_spine1 - 0.01f * H);
  const float y_chest = std::max(y_sh + 0.02f * H - r_chest, y_spine2 + std::abs(r_chest - r_waist) + 0.01f * H);
  auto torso_radius = [&](float y) {
    if (y <= y_spine2) return lerp(r_hip, r_waist, (y - y_bottom) / (y_spine2 - y_bottom));
    return lerp(r_waist, r_chest, std::min(1.0f, (y - y_spine2) / (y_chest - y_spine2)));
  };
  auto torso_part = [&](int joint, float y0, float y1, bool surface, bool skinning) {
    Part part =
        make_part(joint, Vector3f(0, y0, 0), Vector3f(0, y1, 0), torso_radius(y0), torso_radius(y1), surface, skinning);
    squash_along(part, z_axis, p.torso_depth, Vector3f::Zero());
    parts.push_back(part);
  };
  torso_part(kPelvis, y_bottom, y_spine2, true, false);
  torso_part(kSpine2, y_spine2, y_chest, true, false);
  torso_part(kPelvis, y_bottom, y_spine1, false, true);
  torso_part(kSpine1, y_spine1, y_spine2, false, true);
  torso_part(kSpine2, y_spine2, y_spine3, false, true);
  torso_part(kSpine3, y_spine3, y_chest, false, true);

  // Neck and head: the head is an ellipsoid (a squashed sphere) whose top is the crown at y = H.
  const float r_neck = 0.03f * H * std::sqrt(p.limb_thickness);
  parts.push_back(
      make_part(kNeck, Vector3f(0, y_sh - 0.02f * H, -0.005f * H), head_joint, 1.05f * r_neck, r_neck, true, true));
  {
    const float ry = 0.5f * head, rx = p.head_aspect * ry, rz = 1.1f * rx;
    const Vector3f c(0, H - ry, 0.03f * head);
    Part part = make_part(kHead, c, c, ry, ry, true, true);
    part.A = Eigen::Vector3f(ry / rx, 1.0f, ry / rz).asDiagonal();
    part.center = c;
    part.k = 1.0f / std::max({ry / rx, 1.0f, ry / rz});
    parts.push_back(part);
  }

  // Limbs, left then right.
  const float r_upper_arm = 0.027f * limb;
  const float r_ankle = std::min(r_ankle_free, 0.8f * ankle_h);
  for (int side = 0; side < 2; ++side) {
    const Vector3f m = side == 0 ? Vector3f(1, 1, 1) : mirror;
    auto at = [&](const Vector3f& q) { return Vector3f(q.cwiseProduct(m)); };
    const int collar_j = side == 0 ? kLeftCollar : kRightCollar;
    const int shoulder_j = side == 0 ? kLeftShoulder : kRightShoulder;
    const int elbow_j = side == 0 ? kLeftElbow : kRightElbow;
    const int wrist_j = side == 0 ? kLeftWrist : kRightWrist;
    const int hip_j = side == 0 ? kLeftHip : kRightHip;
    const int knee_j = side == 0 ? kLeftKnee : kRightKnee;
    const int ankle_j = side == 0 ? kLeftAnkle : kRightAnkle;
    const int foot_j = side == 0 ? kLeftFoot : kRightFoot;

    // Shoulder girdle from the base of the neck to the shoulder joint: joins arm and torso.
    parts.push_back(make_part(collar_j, Vector3f(0, y_sh - 0.01f * H, -0.005f * H), at(shoulder), 0.035f * H,
                              1.05f * r_upper_arm, true, true));
    parts.push_back(make_part(shoulder_j, at(shoulder), at(elbow), r_upper_arm, 0.019f * limb, true, true));
    parts.push_back(make_part(elbow_j, at(elbow), at(wrist), 0.019f * limb, 0.014f * limb, true, true));
    // Hand: a paddle, flattened across the arm in the plane of the arm's swing (palm down in a T-pose).
    {
      const float r0 = 0.022f * limb, r1 = 0.019f * limb;
      const Vector3f end = wrist + (0.35f * arm - r1) * arm_dir;
      Part part = make_part(wrist_j, at(wrist), at(end), r0, r1, true, true);
      const Vector3f normal = at(Vector3f(std::sin(angle), std::cos(angle), 0)).normalized();
      squash_along(part, normal, 0.5f, at(wrist));
      parts.push_back(part);
    }
    // A bridge from the middle of the pelvis keeps thighs on wide hips attached to a narrow torso.
    parts.push_back(make_part(hip_j, Vector3f(0, y_hip, 0), at(hip), 0.04f * limb, 0.04f * limb, true, false));
    parts.push_back(make_part(hip_j, at(hip), at(knee), 0.05f * limb, 0.032f * limb, true, true));
    parts.push_back(make_part(knee_j, at(knee), at(ankle), 0.032f * limb, r_ankle, true, true));
    // Foot: one surface capsule heel -> toe; skinning splits it at the ball (ankle behind, foot ahead).
    const Vector3f heel(ankle.x(), r_heel, z_heel), toe(x_foot, r_toe, z_toe);
    const Vector3f ball = heel + ball_t * (toe - heel);
    const Vector3f ground = Vector3f::Zero();
    Part whole = make_part(ankle_j, at(heel), at(toe), r_heel, r_toe, true, false);
    Part rear = make_part(ankle_j, at(heel), at(ball), r_heel, r_ball, false, true);
    Part front = make_part(foot_j, at(ball), at(toe), r_ball, r_toe, false, true);
    for (Part* f : {&whole, &rear, &front}) {
      squash_along(*f, y_axis, foot_squash, ground);
      parts.push_back(*f);
    }
  }
  for (Part& part : parts) part.prepare();
  return out;
}

// === Meshing

// Voxels per side of an OpenVDB leaf node.
constexpr int kLeafDim = 8;
constexpr int kLeafVoxels = kLeafDim * kLeafDim * kLeafDim;

void initialize_openvdb() {
  static std::once_flag once;
  std::call_once(once, [] { openvdb::initialize(); });
}

// Keeps the largest connected component of a mesh. At the coarsest voxel sizes a thin end (a hand or
// toe thinner than about a voxel) can be sampled as a separate island; the body is the largest part.
TriMesh largest_component(const TriMesh& mesh) {
  int count = 0;
  const std::vector<int32_t> label = connected_components(mesh.num_vertices(), unique_edges(mesh.F), &count);
  if (count <= 1) return mesh;
  std::vector<int> size(count, 0);
  for (int32_t l : label) ++size[l];
  const int keep = static_cast<int>(std::max_element(size.begin(), size.end()) - size.begin());
  std::vector<int32_t> new_index(label.size(), -1);
  TriMesh out;
  out.V.resize(size[keep], 3);
  int n = 0;
  for (int v = 0; v < mesh.num_vertices(); ++v) {
    if (label[v] != keep) continue;
    new_index[v] = n;
    out.V.row(n++) = mesh.V.row(v);
  }
  int kept_faces = 0;
  for (int f = 0; f < mesh.num_faces(); ++f) kept_faces += label[mesh.F(f, 0)] == keep;
  out.F.resize(kept_faces, 3);
  for (int f = 0, g = 0; f < mesh.num_faces(); ++f) {
    if (label[mesh.F(f, 0)] != keep) continue;
    out.F.row(g++) << new_index[mesh.F(f, 0)], new_index[mesh.F(f, 1)], new_index[mesh.F(f, 2)];
  }
  return out;
}

// Samples the smooth union of `parts` on a level-set grid of voxel size h (metres). The field is
// sampled only in the leaf nodes (8^3 voxels) it may cross: a leaf is skipped when the bounds
// min_i d_i - B <= f <= min_i d_i (B the largest smooth-union bump) keep f beyond +-2 h over the whole
// leaf; signedFloodFill then gives the skipped space its inside or outside sign.
openvdb::FloatGrid::Ptr sample_band(const std::vector<Part>& parts, float blend, float h) {
  initialize_openvdb();
  const int P = static_cast<int>(parts.size());
  AMT_CHECK(P <= 64, "sample_band: expected at most 64 parts, found ", P);
  Eigen::AlignedBox3f box;
  for (const Part& part : parts) box.extend(part.bounds());
  const float pad = blend + 3 * h;
  const Eigen::Array3i lo = ((box.min().array() - pad) / h).floor().cast<int>();
  const Eigen::Array3i hi = ((box.max().array() + pad) / h).ceil().cast<int>();
  auto leaf_floor = [](int i) { return (i >= 0 ? i : i - (kLeafDim - 1)) / kLeafDim; };
  const Eigen::Array3i leaf_lo(leaf_floor(lo.x()), leaf_floor(lo.y()), leaf_floor(lo.z()));
  const Eigen::Array3i leaf_hi(leaf_floor(hi.x()), leaf_floor(hi.y()), leaf_floor(hi.z()));
  const Eigen::Array3i leaf_n = leaf_hi - leaf_lo + 1;
  const int num_leaves = leaf_n.prod();

  // Pass 1: which leaves may hold the surface.
  const float half_diagonal = 0.5f * std::sqrt(3.0f) * (kLeafDim - 1) * h;
  std::vector<uint8_t> crossing(num_leaves, 0);
  auto leaf_origin = [&](int index) {
    const int x = index % leaf_n.x(), y = (index / leaf_n.x()) % leaf_n.y(), z = index / (leaf_n.x() * leaf_n.y());
    return openvdb::Coord((leaf_lo.x() + x) * kLeafDim, (leaf_lo.y() + y) * kLeafDim, (leaf_lo.z() + z) * kLeafDim);
  };
  // Parts that can matter inside a leaf of centre c: within 2 R + blend of the minimum at c.
  auto candidates = [&](const Vector3f& c, std::vector<int>& out, float* min_value) {
    std::array<float, 64> d;
    float m = std::numeric_limits<float>::infinity();
    for (int i = 0; i < P; ++i) {
      d[i] = parts[i].value(c);
      m = std::min(m, d[i]);
    }
    out.clear();
    for (int i = 0; i < P; ++i) {
      if (d[i] - half_diagonal < m + half_diagonal + blend) out.push_back(i);
    }
    *min_value = m;
  };
#pragma omp parallel
  {
    std::vector<int> cand;
#pragma omp for schedule(dynamic, 64)
    for (int index = 0; index < num_leaves; ++index) {
      const openvdb::Coord o = leaf_origin(index);
      const Vector3f c = h * Vector3f(o.x() + 3.5f, o.y() + 3.5f, o.z() + 3.5f);
      float m;
      candidates(c, cand, &m);
      const float bump = 0.25f * blend * static_cast<float>(cand.size() - 1);
      const bool outside = m - half_diagonal - bump > 2 * h;
      const bool inside = m + half_diagonal < -2 * h;
      crossing[index] = !outside && !inside;
    }
  }
  std::vector<int> active;
  for (int index = 0; index < num_leaves; ++index) {
    if (crossing[index]) active.push_back(index);
  }

  // Pass 2: sample the active leaves, in OpenVDB's voxel order within a leaf (x major, z minor).
  const int num_active = static_cast<int>(active.size());
  std::vector<float> values(static_cast<size_t>(num_active) * kLeafVoxels);
#pragma omp parallel
  {
    std::vector<int> cand;
    std::array<float, 64> d;
#pragma omp for schedule(dynamic, 8)
    for (int n = 0; n < num_active; ++n) {
      const openvdb::Coord o = leaf_origin(active[n]);
      const Vector3f c = h * Vector3f(o.x() + 3.5f, o.y() + 3.5f, o.z() + 3.5f);
      float m;
      candidates(c, cand, &m);
      const int count = static_cast<int>(cand.size());
      float* out = values.data() + static_cast<size_t>(n) * kLeafVoxels;
      for (int x = 0; x < kLeafDim; ++x) {
        for (int y = 0; y < kLeafDim; ++y) {
          for (int z = 0; z < kLeafDim; ++z) {
            const Vector3f q = h * Vector3f(float(o.x() + x), float(o.y() + y), float(o.z() + z));
            for (int i = 0; i < count; ++i) d[i] = parts[cand[i]].value(q);
            *out++ = smooth_union(d.data(), count, blend);
          }
        }
      }
    }
  }

  const float background = 3 * h;
  openvdb::FloatGrid::Ptr grid = openvdb::FloatGrid::create(background);
  grid->setTransform(openvdb::math::Transform::createLinearTransform(h));
  grid->setGridClass(openvdb::GRID_LEVEL_SET);
  openvdb::FloatTree& tree = grid->tree();
  for (int n = 0; n < num_active; ++n) {
    auto* leaf = new openvdb::FloatTree::LeafNodeType(leaf_origin(active[n]), background, false);
    const float* v = values.data() + static_cast<size_t>(n) * kLeafVoxels;
    for (int i = 0; i < kLeafVoxels; ++i) leaf->setValueOn(i, std::clamp(v[i], -background, background));
    tree.addLeaf(leaf);
  }
  openvdb::tools::signedFloodFill(tree);
  return grid;
}

// The zero set of a level-set grid as an outward-facing triangle mesh, its largest component only.
// adaptivity 0 gives a uniform mesh of about one vertex per surface voxel; larger values (up to 1)
// merge voxels where the surface is flat.
TriMesh polygonize(const openvdb::FloatGrid& grid, double adaptivity) {
  std::vector<openvdb::Vec3s> points;
  std::vector<openvdb::Vec3I> triangles;
  std::vector<openvdb::Vec4I> quads;
  openvdb::tools::volumeToMesh(grid, points, triangles, quads, 0.0, adaptivity);

  TriMesh mesh;
  mesh.V.resize(static_cast<Eigen::Index>(points.size()), 3);
  for (size_t i = 0; i < points.size(); ++i)
    mesh.V.row(static_cast<Eigen::Index>(i)) << points[i][0], points[i][1], points[i][2];
  mesh.F.resize(static_cast<Eigen::Index>(triangles.size() + 2 * quads.size()), 3);
  Eigen::Index f = 0;
  for (const openvdb::Vec3I& t : triangles) mesh.F.row(f++) << int(t[0]), int(t[1]), int(t[2]);
  for (const openvdb::Vec4I& q : quads) {
    // Split along the shorter diagonal.
    const float d02 = (mesh.V.row(q[0]) - mesh.V.row(q[2])).squaredNorm();
    const float d13 = (mesh.V.row(q[1]) - mesh.V.row(q[3])).squaredNorm();
    if (d02 <= d13) {
      mesh.F.row(f++) << int(q[0]), int(q[1]), int(q[2]);
      mesh.F.row(f++) << int(q[0]), int(q[2]), int(q[3]);
    } else {
      mesh.F.row(f++) << int(q[0]), int(q[1]), int(q[3]);
      mesh.F.row(f++) << int(q[1]), int(q[2]), int(q[3]);
    }
  }

  mesh = largest_component(mesh);

  // volumeToMesh orders polygons for an inside-negative field so that their normals point out of the
  // negative region; checked here by the signed volume rather than trusted, and flipped if needed.
  double volume = 0;
  for (Eigen::Index t = 0; t < mesh.F.rows(); ++t) {
    const Eigen::Vector3d a = mesh.V.row(mesh.F(t, 0)).cast<double>(), b = mesh.V.row(mesh.F(t, 1)).cast<double>(),
                          c = mesh.V.row(mesh.F(t, 2)).cast<double>();
    volume += a.dot(b.cross(c));
  }
  if (volume < 0) mesh.F.col(1).swap(mesh.F.col(2));
  return mesh;
}

// Rough surface area (m^2) of the body: the sum of the parts' areas, overlaps counted twice.
double estimated_area(const std::vector<Part>& parts) {
  double area = 0;
  for (const Part& part : parts) {
    const double l = std::sqrt(part.l2), r = 0.5 * (part.ra + part.rb);
    area += 2 * M_PI * r * l * part.k + 4 * M_PI * r * r * part.k;
  }
  return area;
}

// True when every directed edge of the faces occurs once and its reverse once: closed, manifold
// and consistently oriented.
bool is_closed_manifold(const TriMesh& mesh) {
  std::vector<int64_t> directed, reversed;
  directed.reserve(3 * static_cast<size_t>(mesh.num_faces()));
  reversed.reserve(directed.capacity());
  for (int f = 0; f < mesh.num_faces(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int64_t i = mesh.F(f, k), j = mesh.F(f, (k + 1) % 3);
      directed.push_back((i << 32) | j);
      reversed.push_back((j << 32) | i);
    }
  }
  std::sort(directed.begin(), directed.end());
  std::sort(reversed.begin(), reversed.end());
  return std::adjacent_find(directed.begin(), directed.end()) == directed.end() && directed == reversed;
}

// Meshes the surface parts with about target_vertices vertices (aim: within 4 %). A uniform mesh has
// about c area / h^2 vertices, so the voxel size h is corrected by sqrt(count / target). Voxels much
// larger than the thinnest part (hand, toes) would erode it, so h stops at twice its half-thickness
// (measured: 60 sampled bodies at 2k vertices keep every joint inside); smaller targets are reached
// from that grid by OpenVDB's adaptive meshing, which merges voxels on flat regions, with the
// adaptivity found by bisection. An adaptive mesh that is not closed and manifold is never returned.
TriMesh mesh_body(const Layout& layout, int target_vertices) {
  std::vector<Part> surface;
  float thinnest = std::numeric_limits<float>::infinity();
  for (const Part& part : layout.parts) {
    if (!part.surface) continue;
    surface.push_back(part);
    thinnest = std::min(thinnest, part.k * std::min(part.ra, part.rb));
  }
  const double h_limit = 2.0 * thinnest;
  TriMesh best;
  double best_error = std::numeric_limits<double>::infinity();
  auto consider = [&](TriMesh mesh) {
    const double ratio = static_cast<double>(mesh.num_vertices()) / target_vertices;
    if (std::abs(ratio - 1.0) < best_error) {
      best_error = std::abs(ratio - 1.0);
      best = std::move(mesh);
    }
    return ratio;
  };
  constexpr double kTolerance = 0.04;

  // Uniform meshes. First guess: about 1.2 vertices per h^2 of area (overlaps make the estimate large).
  double h = std::min(h_limit, std::sqrt(1.2 * estimated_area(surface) / target_vertices));
  double ratio = 1.0;
  for (int attempt = 0; attempt < 6; ++attempt) {
    TriMesh mesh = polygonize(*sample_band(surface, layout.blend, static_cast<float>(h)), 0.0);
    if (!is_closed_manifold(mesh)) {  // not seen in practice; a slightly different grid avoids it
      h *= 0.99;
      continue;
    }
    ratio = consider(std::move(mesh));
    if (best_error <= kTolerance) return best;
    if (h >= h_limit && ratio > 1.0) break;  // too many vertices even at the coarsest allowed voxels
    h = std::min(h_limit, h * std::sqrt(std::clamp(ratio, 0.25, 4.0)));
  }

  if (best.num_vertices() > 0 && ratio <= 1.0) return best;

  // Adaptive meshes of the coarsest allowed grid: the vertex count falls as the adaptivity grows.
  const openvdb::FloatGrid::Ptr grid = sample_band(surface, layout.blend, static_cast<float>(h_limit));
  double lo = 0.0, hi = 1.0;
  for (int attempt = 0; attempt < 10; ++attempt) {
    const double adaptivity = 0.5 * (lo + hi);
    TriMesh mesh = polygonize(*grid, adaptivity);
    if (!is_closed_manifold(mesh)) {
      hi = adaptivity;
      continue;
    }
    const double count_ratio = consider(std::move(mesh));
    if (best_error <= kTolerance) break;
    (count_ratio > 1.0 ? lo : hi) = adaptivity;
  }
  AMT_CHECK(best.num_vertices() > 0, "generate_body: meshing failed to give a closed manifold surface for ",
            target_vertices, " vertices");
  return best;
}

// === Skinning

// Side of a canonical joint: +1 left, -1 right, 0 on the midline.
int joint_side(int j) {
  const std::string& name = canonical_joint_names()[j];
  if (name.rfind("left_", 0) == 0) return 1;
  if (name.rfind("right_", 0) == 0) return -1;
  return 0;
}

// Number of bones between every pair of canonical joints in the kinematic tree.
std::array<std::array<int, kCanonicalJointCount>, kCanonicalJointCount> hierarchy_distances() {
  const std::vector<int32_t>& parents = canonical_joint_parents();
  std::array<std::array<int, kCanonicalJointCount>, kCanonicalJointCount> dist;
  for (int i = 0; i < kCanonicalJointCount; ++i) {
    std::array<int, kCanonicalJointCount> up;  // steps from i up to each ancestor, -1 if not one
    up.fill(-1);
    for (int a = i, steps = 0; a >= 0; a = parents[a], ++steps) up[a] = steps;
    for (int j = 0; j < kCanonicalJointCount; ++j) {
      int steps = 0, a = j;
      while (up[a] < 0) {
        a = parents[a];
        ++steps;
      }
      dist[i][j] = steps + up[a];
    }
  }
  return dist;
}

// Width of the weight falloff in units of the local radius of the closest part: joints blend over
// about 1.7 radii on either side.
constexpr float kFalloffRadii = 1.0f;
// Hierarchy neighbourhood of the closest part's joint that may take weight.
constexpr int kMaxHierarchyDistance = 2;
// Laplacian smoothing of the weights over the mesh edges.
constexpr int kSmoothingIterations = 4;
constexpr float kSmoothingStep = 0.5f;

SparseWeights body_weights(const Layout& layout, const TriMesh& mesh) {
  std::vector<Part> skinning;
  for (const Part& part : layout.parts) {
    if (part.skinning) skinning.push_back(part);
  }
  const auto hierarchy = hierarchy_distances();
  const int N = mesh.num_vertices(), J = kCanonicalJointCount;
  const MatrixX2i E = unique_edges(mesh.F);
  MatrixXfR W = MatrixXfR::Zero(N, J);
#pragma omp parallel for schedule(static)
  for (int v = 0; v < N; ++v) {
    const Vector3f p = mesh.V.row(v).transpose();
    std::array<float, kCanonicalJointCount> d;
    d.fill(std::numeric_limits<float>::infinity());
    int closest = 0;
    float closest_value = std::numeric_limits<float>::infinity();
    for (int i = 0; i < static_cast<int>(skinning.size()); ++i) {
      const float value = skinning[i].value(p);
      d[skinning[i].joint] = std::min(d[skinning[i].joint], value);
      if (value < closest_value) {
        closest_value = value;
        closest = i;
      }
    }
    const int owner = skinning[closest].joint;
    const float width = kFalloffRadii * skinning[closest].radius_near(p);
    float sum = 0;
    for (int j = 0; j < J; ++j) {
      if (hierarchy[owner][j] > kMaxHierarchyDistance || joint_side(owner) * joint_side(j) < 0) continue;
      const float t = (d[j] - closest_value) / width;
      if (t >= 1) continue;
      const float w = 1 - t * t * (3 - 2 * t);  // 1 - smoothstep: 1 at the closest part, 0 one width away
      W(v, j) = w;
      sum += w;
    }
    W.row(v) /= sum;
  }

  const Adjacency adjacency = vertex_adjacency(N, E);
  MatrixXfR next(N, J);
  for (int iteration = 0; iteration < kSmoothingIterations; ++iteration) {
#pragma omp parallel for schedule(static)
    for (int v = 0; v < N; ++v) {
      Eigen::RowVectorXf mean = Eigen::RowVectorXf::Zero(J);
      for (int e = adjacency.offsets[v]; e < adjacency.offsets[v + 1]; ++e) mean += W.row(adjacency.neighbors[e]);
      const int degree = adjacency.degree(v);
      next.row(v) = degree > 0 ? ((1 - kSmoothingStep) * W.row(v) + (kSmoothingStep / degree) * mean).eval() : W.row(v);
    }
    W.swap(next);
  }
  return sparsify_weights(W);
}

void check_range(const char* field, float value, float lo, float hi) {
  AMT_CHECK(std::isfinite(value) && value >= lo && value <= hi, "body parameters: ", field, ": expected a value in [",
            lo, ", ", hi, "], found ", value);
}

}  // namespace

void validate_body_params(const BodyParams& p) {
  AMT_CHECK(std::isfinite(p.height) && p.height > 0 && p.height <= 5,
            "body parameters: height: expected metres in (0, 5], found ", p.height);
  check_range("head_ratio", p.head_ratio, 0.05f, 0.4f);
  check_range("head_aspect", p.head_aspect, 0.5f, 1.5f);
  check_range("neck_ratio", p.neck_ratio, 0.0f, 0.15f);
  check_range("leg_ratio", p.leg_ratio, 0.3f, 0.8f);
  check_range("arm_ratio", p.arm_ratio, 0.1f, 0.5f);
  check_range("limb_thickness", p.limb_thickness, 0.4f, 2.5f);
  check_range("shoulder_width", p.shoulder_width, 0.08f, 0.4f);
  check_range("hip_width", p.hip_width, 0.04f, 0.25f);
  check_range("chest_radius", p.chest_radius, 0.04f, 0.2f);
  check_range("waist_radius", p.waist_radius, 0.03f, 0.2f);
  check_range("hip_radius", p.hip_radius, 0.04f, 0.2f);
  check_range("torso_depth", p.torso_depth, 0.4f, 1.2f);
  check_range("arm_angle_deg", p.arm_angle_deg, -10.0f, 60.0f);
}

BodyParams sample_body_params(std::mt19937& rng) {
  BodyParams p;
  const float s = uniform01(rng);  // 0 tall adult, 1 chibi
  p.height = lerp(1.80f, 1.0f, s) * uniform(rng, 0.94f, 1.06f);
  p.head_ratio = lerp(0.125f, 0.26f, s) * uniform(rng, 0.93f, 1.07f);
  p.head_aspect = lerp(0.80f, 0.95f, s) * uniform(rng, 0.95f, 1.05f);
  p.neck_ratio = lerp(0.05f, 0.025f, s) * uniform(rng, 0.8f, 1.2f);
  p.leg_ratio = lerp(0.62f, 0.50f, s) * uniform(rng, 0.94f, 1.06f);
  p.arm_ratio = uniform(rng, 0.27f, 0.33f);
  p.limb_thickness = lerp(1.0f, 1.2f, s) * uniform(rng, 0.8f, 1.2f);
  p.shoulder_width = lerp(0.21f, 0.20f, s) * uniform(rng, 0.88f, 1.12f);
  p.hip_width = lerp(0.105f, 0.11f, s) * uniform(rng, 0.9f, 1.1f);
  p.chest_radius = lerp(0.09f, 0.10f, s) * uniform(rng, 0.88f, 1.12f);
  p.waist_radius = p.chest_radius * uniform(rng, 0.72f, 0.92f);
  p.hip_radius = lerp(0.095f, 0.10f, s) * uniform(rng, 0.9f, 1.12f);
  p.torso_depth = uniform(rng, 0.62f, 0.82f);
  const bool a_pose = (rng() >> 31) != 0;
  p.arm_angle_deg = a_pose ? uniform(rng, 25.0f, 42.0f) : uniform(rng, 0.0f, 6.0f);
  return p;
}

BodyParams sample_body_params(uint64_t seed) {
  std::seed_seq seq{static_cast<uint32_t>(seed), static_cast<uint32_t>(seed >> 32)};
  std::mt19937 rng(seq);
  return sample_body_params(rng);
}

Skeleton body_skeleton(const BodyParams& params) {
  return body_layout(params).skeleton;
}

GeneratedBody generate_body(const BodyParams& params, int target_vertices) {
  AMT_CHECK(target_vertices >= kMinBodyVertices && target_vertices <= kMaxBodyVertices,
            "generate_body: target_vertices: expected a count in [", kMinBodyVertices, ", ", kMaxBodyVertices,
            "], found ", target_vertices);
  const Layout layout = body_layout(params);
  GeneratedBody body;
  body.params = params;
  body.skeleton = layout.skeleton;
  body.mesh = mesh_body(layout, target_vertices);
  body.weights = body_weights(layout, body.mesh);
  return body;
}

}  // namespace amt
