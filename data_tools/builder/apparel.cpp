#include "data_tools/builder/apparel.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>

#include "data_tools/geometry/error.h"

namespace amt {

namespace {

using Eigen::Matrix3f;
using Eigen::Vector3f;

constexpr float kPi = 3.14159265358979f;
constexpr float kDegrees = kPi / 180.0f;
constexpr float kGravity = 9.8f;
constexpr uint8_t kBodyGroup = 0;
constexpr uint8_t kApparelGroup = 1;

// === Random draws from raw engine output (the same with every standard library)

float uniform01(std::mt19937& rng) {
  return static_cast<float>(rng() >> 8) * (1.0f / 16777216.0f);
}

float uniform(std::mt19937& rng, float lo, float hi) {
  return lo + (hi - lo) * uniform01(rng);
}

int uniform_int(std::mt19937& rng, int lo, int hi) {
  return lo + static_cast<int>(rng() % static_cast<uint32_t>(hi - lo + 1));
}

float lerp(float a, float b, float t) {
  return a + (b - a) * t;
}

// === Geometry helpers

// Closest point on segment [a, b] to p; `t` receives its parameter in [0, 1].
Vector3f closest_on_segment(const Vector3f& p, const Vector3f& a, const Vector3f& b, float* t = nullptr) {
  const Vector3f ab = b - a;
  const float l2 = ab.squaredNorm();
  const float s = l2 > 1e-12f ? std::clamp((p - a).dot(ab) / l2, 0.0f, 1.0f) : 0.0f;
  if (t) *t = s;
  return a + s * ab;
}

// A rotation whose Y axis is `y` and whose X axis is `x_hint` made orthogonal to it.
Eigen::Quaternionf frame_rotation(const Vector3f& y, const Vector3f& x_hint) {
  const Vector3f Y = y.normalized();
  Vector3f X = x_hint - x_hint.dot(Y) * Y;
  if (X.squaredNorm() < 1e-8f) X = Y.unitOrthogonal();
  X.normalize();
  const Vector3f Z = X.cross(Y);
  Matrix3f R;
  R.col(0) = X;
  R.col(1) = Y;
  R.col(2) = Z;
  return Eigen::Quaternionf(R).normalized();
}

// A capsule between a and b (world, metres) of radius r, on canonical joint `joint`.
struct Capsule {
  Vector3f a, b;
  float r = 0;
  int joint = 0;
};

// === Body measurements

// What the apparel builder needs to know about a body: its joints, proportions, collision capsules and the torso's
// cross-sections.
struct BodyInfo {
  const GeneratedBody* body = nullptr;
  MatrixX3f J;                   // rest joints
  std::vector<int> dominant;     // per body vertex: the joint with the largest weight
  std::vector<Capsule> capsules;  // collision capsules (with margin)
  std::vector<int32_t> joint_body;
  float H = 0, head_h = 0;
  Vector3f head_center = Vector3f::Zero(), head_radii = Vector3f::Zero();

  Vector3f joint(int j) const { return J.row(j).transpose(); }

  bool is_torso(int j) const { return j == kPelvis || j == kSpine1 || j == kSpine2 || j == kSpine3; }

  // Half-width a, half-depth b and depth centre zc of the torso surface within +-band of height y.
  void torso_section(float y, float band, float* a, float* b, float* zc) const {
    const MatrixX3f& V = body->mesh.V;
    float xmax = 0, zmin = std::numeric_limits<float>::infinity(), zmax = -zmin;
    for (int i = 0; i < V.rows(); ++i) {
      if (!is_torso(dominant[i]) || std::abs(V(i, 1) - y) > band) continue;
      xmax = std::max(xmax, std::abs(V(i, 0)));
      zmin = std::min(zmin, V(i, 2));
      zmax = std::max(zmax, V(i, 2));
    }
    if (!(zmax > zmin)) {  // no torso vertex there: fall back on the parameters
      xmax = body->params.waist_radius * H;
      zmin = -xmax * body->params.torso_depth;
      zmax = -zmin;
    }
    *a = xmax;
    *b = 0.5f * (zmax - zmin);
    *zc = 0.5f * (zmax + zmin);
  }

  // Pushes p out of every collision capsule until it is at least `clearance` outside each (a few passes).
  void push_out(Vector3f& p, float clearance, const Vector3f& fallback) const {
    for (int pass = 0; pass < 6; ++pass) {
      bool moved = false;
      for (const Capsule& c : capsules) {
        const Vector3f q = closest_on_segment(p, c.a, c.b);
        const float need = c.r + clearance;
        const Vector3f d = p - q;
        const float dist = d.norm();
        if (dist >= need) continue;
        const Vector3f dir = dist > 1e-6f ? Vector3f(d / dist) : fallback;
        p = q + need * dir;
        moved = true;
      }
      if (!moved) break;
    }
  }
};

// A capsule along [a, b] enclosing the vertices dominated by `joint` whose projections fall inside the segment
// (t in [t0, t1]), plus margin; `fallback` radius when no vertex qualifies.
Capsule fit_capsule(const BodyInfo& info, int joint, const Vector3f& a, const Vector3f& b, float margin,
                    float fallback, float t0 = 0.1f, float t1 = 0.9f) {
  const MatrixX3f& V = info.body->mesh.V;
  float r = 0;
  for (int i = 0; i < V.rows(); ++i) {
    if (info.dominant[i] != joint) continue;
    const Vector3f p = V.row(i).transpose();
    float t;
    const Vector3f q = closest_on_segment(p, a, b, &t);
    if (t < t0 || t > t1) continue;
    r = std::max(r, (p - q).norm());
  }
  Capsule c;
  c.a = a;
  c.b = b;
  c.r = (r > 0 ? r : fallback) + margin;
  c.joint = joint;
  return c;
}

// Collision capsules of a body (see body_collision_capsules) into info.capsules / info.joint_body.
void build_capsules(BodyInfo& info, float margin) {
  const GeneratedBody& g = *info.body;
  const float H = info.H;
  std::vector<Capsule>& caps = info.capsules;
  std::vector<int32_t>& jb = info.joint_body;
  jb.assign(kCanonicalJointCount, -1);
  auto add = [&](const Capsule& c, int owner) {
    if (owner >= 0 && jb[owner] < 0) jb[owner] = static_cast<int32_t>(caps.size());
    caps.push_back(c);
  };

  // Torso: horizontal capsules (stadiums across X) stacked from the hip joints to below the shoulders, each
  // fitted to the torso's cross-section at its height and carried by the spine joint below it.
  const float y_lo = info.joint(kLeftHip).y();
  const float y_hi = info.joint(kLeftShoulder).y() - 0.01f * H;
  const int levels = std::max(4, static_cast<int>(std::ceil((y_hi - y_lo) / (0.04f * H))) + 1);
  const float gap = (y_hi - y_lo) / static_cast<float>(levels - 1);
  std::vector<std::pair<int, Capsule>> torso;
  for (int l = 0; l < levels; ++l) {
    const float y = y_lo + gap * static_cast<float>(l);
    float a, b, zc;
    info.torso_section(y, 0.5f * gap + 0.005f * H, &a, &b, &zc);
    int joint = kPelvis;
    for (int j : {kSpine1, kSpine2, kSpine3})
      if (info.joint(j).y() <= y) joint = j;
    const float half = std::max(a - b, 0.001f);
    Capsule c;
    c.a = Vector3f(-half, y, zc);
    c.b = Vector3f(half, y, zc);
    c.r = std::max(b, std::min(a, b)) + margin;
    c.joint = joint;
    torso.emplace_back(joint, c);
  }
  // Each spine joint's main body is the level nearest to it.
  for (int j : {kPelvis, kSpine1, kSpine2, kSpine3}) {
    int best = 0;
    for (size_t l = 0; l < torso.size(); ++l)
      if (std::abs(torso[l].second.a.y() - info.joint(j).y()) < std::abs(torso[best].second.a.y() - info.joint(j).y()))
        best = static_cast<int>(l);
    jb[j] = static_cast<int32_t>(best);  // torso capsules are added first, in level order
  }
  for (auto& [owner, c] : torso) caps.push_back(c);

  // Neck and head.
  add(fit_capsule(info, kNeck, info.joint(kNeck), info.joint(kHead), margin, 0.03f * H, 0.0f, 0.8f), kNeck);
  {
    Capsule c;
    const Vector3f& r = info.head_radii;
    const float radius = std::max(r.x(), r.z());
    const float half = std::max(r.y() - radius, 0.001f);
    c.a = info.head_center - Vector3f(0, half, 0);
    c.b = info.head_center + Vector3f(0, half, 0);
    c.r = radius + margin;
    c.joint = kHead;
    add(c, kHead);
  }
  // Limbs: a capsule per bone segment, fitted to the vertices the segment's joint dominates.
  const float limb = g.params.limb_thickness * H;
  for (int side = 0; side < 2; ++side) {
    const int collar = side == 0 ? kLeftCollar : kRightCollar, shoulder = side == 0 ? kLeftShoulder : kRightShoulder;
    const int elbow = side == 0 ? kLeftElbow : kRightElbow, wrist = side == 0 ? kLeftWrist : kRightWrist;
    const int hip = side == 0 ? kLeftHip : kRightHip, knee = side == 0 ? kLeftKnee : kRightKnee;
    const int ankle = side == 0 ? kLeftAnkle : kRightAnkle, foot = side == 0 ? kLeftFoot : kRightFoot;
    add(fit_capsule(info, collar, info.joint(collar), info.joint(shoulder), margin, 0.03f * H), collar);
    add(fit_capsule(info, shoulder, info.joint(shoulder), info.joint(elbow), margin, 0.025f * limb), shoulder);
    add(fit_capsule(info, elbow, info.joint(elbow), info.joint(wrist), margin, 0.018f * limb), elbow);
    {
      // Hand: from the wrist to the farthest hand vertex along the forearm's direction.
      const Vector3f w = info.joint(wrist), dir = (w - info.joint(elbow)).normalized();
      float reach = 0.05f * H;
      for (int i = 0; i < g.mesh.V.rows(); ++i)
        if (info.dominant[i] == wrist) reach = std::max(reach, (Vector3f(g.mesh.V.row(i)) - w).dot(dir));
      Capsule c = fit_capsule(info, wrist, w, w + 0.8f * reach * dir, margin, 0.02f * limb, 0.0f, 1.0f);
      c.b = w + std::max(0.5f * reach, reach - c.r) * dir;
      add(c, wrist);
    }
    add(fit_capsule(info, hip, info.joint(hip), info.joint(knee), margin, 0.045f * limb), hip);
    add(fit_capsule(info, knee, info.joint(knee), info.joint(ankle), margin, 0.03f * limb), knee);
    add(fit_capsule(info, ankle, info.joint(ankle), info.joint(foot), margin, 0.022f * limb, 0.0f, 1.0f), ankle);
    {
      const Vector3f f = info.joint(foot);
      float reach = 0.02f * H;
      for (int i = 0; i < g.mesh.V.rows(); ++i)
        if (info.dominant[i] == foot) reach = std::max(reach, g.mesh.V(i, 2) - f.z());
      Capsule c = fit_capsule(info, foot, f, f + Vector3f(0, 0, reach), margin, 0.018f * limb, 0.0f, 1.0f);
      c.b = f + Vector3f(0, 0, std::max(0.3f * reach, reach - c.r));
      add(c, foot);
    }
  }
  for (int j = 0; j < kCanonicalJointCount; ++j) AMT_CHECK(jb[j] >= 0, "apparel: no collision body for joint ", j);
}

BodyInfo measure_body(const GeneratedBody& body, float margin) {
  AMT_CHECK(is_canonical(body.skeleton), "dress_character: expected a body on the canonical 22-joint skeleton");
  validate_mesh(body.mesh, "dress_character: body mesh");
  AMT_CHECK(body.weights.num_vertices() == body.mesh.num_vertices(), "dress_character: body weights: expected ",
            body.mesh.num_vertices(), " rows, found ", body.weights.num_vertices());
  BodyInfo info;
  info.body = &body;
  info.J = body.skeleton.rest_joints;
  info.H = body.params.height;
  info.head_h = body.params.head_ratio * info.H;
  const float ry = 0.5f * info.head_h, rx = body.params.head_aspect * ry;
  info.head_radii = Vector3f(rx, ry, 1.1f * rx);
  info.head_center = Vector3f(0, info.H - ry, 0.03f * info.head_h);
  const int n = body.mesh.num_vertices();
  info.dominant.resize(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    int best = 0;
    for (int k = 1; k < kMaxInfluences; ++k)
      if (body.weights.weights(i, k) > body.weights.weights(i, best)) best = k;
    info.dominant[i] = body.weights.indices(i, best);
  }
  build_capsules(info, margin);
  return info;
}

PhysicsBody capsule_body(const Capsule& c, const std::string& name) {
  PhysicsBody b;
  b.name = name;
  b.bone = c.joint;
  b.shape = PhysicsShape::kCapsule;
  const Vector3f axis = c.b - c.a;
  const float len = axis.norm();
  b.size = Vector3f(c.r, std::max(len, 1e-4f), 0);
  b.rest.position = 0.5f * (c.a + c.b);
  b.rest.rotation = len > 1e-6f ? Eigen::Quaternionf::FromTwoVectors(Vector3f::UnitY(), axis / len)
                                : Eigen::Quaternionf::Identity();
  b.mode = PhysicsMode::kFollowBone;
  b.friction = 0.2f;
  b.group = kBodyGroup;
  b.non_collision_mask = 1u << kBodyGroup;
  return b;
}

// === Apparel layout: chains, sheets and tubes

// A chain of n apparel bones through points p_0 .. p_n (bone k from p_k to p_{k+1}), with a unit "side" vector per
// point across the sheet (the X axis of the bone's body frame) and the radius of its bodies.
struct Chain {
  std::vector<Vector3f> points;
  std::vector<Vector3f> sides;
  std::vector<float> radii;  // per bone
  int first_bone = -1;       // rig bone of bone 0
  int first_body = -1;       // rig body of bone 0

  int num_bones() const { return static_cast<int>(points.size()) - 1; }
  float length() const {
    float l = 0;
    for (size_t k = 1; k < points.size(); ++k) l += (points[k] - points[k - 1]).norm();
    return l;
  }
  // Position and side at bone coordinate x in [0, n] (bone k covers [k, k + 1]).
  Vector3f at(float x) const {
    const int n = num_bones();
    const int k = std::clamp(static_cast<int>(std::floor(x)), 0, n - 1);
    const float f = std::clamp(x - static_cast<float>(k), 0.0f, 1.0f);
    return (1 - f) * points[k] + f * points[k + 1];
  }
  Vector3f side_at(float x) const {
    const int n = num_bones();
    const int k = std::clamp(static_cast<int>(std::floor(x)), 0, n - 1);
    const float f = std::clamp(x - static_cast<float>(k), 0.0f, 1.0f);
    return ((1 - f) * sides[k] + f * sides[k + 1]).normalized();
  }
};

// A sheet over consecutive chains [first, first + count) of a piece: closed (a ring) or open; one chain makes a
// ribbon of the given width. A band (rows from the root ring towards band_top, skinned to the attachment joint)
// connects it to the body garment.
struct Sheet {
  int first = 0, count = 0;
  bool closed = false;
  float ribbon_width = 0;
  std::vector<Vector3f> band_top;  // per chain; empty for no band
  float pleat_depth = 0;           // metres; pleats alternate in and out twice between neighbouring chains
};

// A closed tube around one chain, radius tapering from r0 at the root to r1 at the tip.
struct Tube {
  int chain = 0;
  float r0 = 0, r1 = 0;
};

// Physics of a piece's chains.
struct ChainPhysics {
  float mass = 0.08f;                  // per body, kg
  float linear_damping = 0.2f, angular_damping = 0.25f;
  float swing = 40 * kDegrees;         // angular limit about the bone's X axis (swing in the chain's plane)
  float sway = 20 * kDegrees;          // about its Z axis (sideways)
  float twist = 5 * kDegrees;          // about its Y axis (the bone)
  float stiffness = 1.0f;              // spring: stiffness * (gravity torque of the chain below the joint) per rad
  bool ring_joints = false;            // ball joints with slack between neighbouring chains' bones
};

struct PieceLayout {
  ApparelKind kind = ApparelKind::kPleatedSkirt;
  int attach = kPelvis;
  bool connected = false;
  std::vector<Chain> chains;
  std::vector<Sheet> sheets;
  std::vector<Tube> tubes;
  ChainPhysics physics;
  int vertex_budget = 500;
};

// Grows a chain of n bones of total length `length` from `root` (already clear of the body), starting along dir0
// and bending towards straight down by `droop` (0: straight; 1: down by the end), each point pushed clear of the
// body capsules by `clearance` plus its body radius. `side` is the hint for the points' side vectors.
Chain grow_chain(const BodyInfo& info, const Vector3f& root, const Vector3f& dir0, float length, int n, float droop,
                 float radius, float clearance, const Vector3f& side) {
  Chain c;
  c.points.push_back(root);
  const float seg = length / static_cast<float>(n);
  const Vector3f down(0, -1, 0);
  for (int k = 1; k <= n; ++k) {
    const float t = std::min(1.0f, droop * static_cast<float>(k - 1) / static_cast<float>(std::max(1, n - 1)));
    const Vector3f dir = (dir0.normalized() * (1 - t) + down * t).normalized();
    const Vector3f& prev = c.points.back();
    Vector3f p = prev + seg * dir;
    for (int it = 0; it < 3; ++it) {
      info.push_out(p, radius + clearance, dir0.normalized());
      p = prev + seg * (p - prev).normalized();
    }
    info.push_out(p, radius + clearance, dir0.normalized());
    c.points.push_back(p);
  }
  for (int k = 0; k <= n; ++k) {
    const Vector3f t = k < n ? Vector3f(c.points[k + 1] - c.points[k]) : Vector3f(c.points[k] - c.points[k - 1]);
    Vector3f s = side - side.dot(t.normalized()) * t.normalized();
    if (s.squaredNorm() < 1e-8f) s = t.unitOrthogonal();
    c.sides.push_back(s.normalized());
  }
  c.radii.assign(static_cast<size_t>(n), radius);
  return c;
}

// Root point on the head ellipsoid at azimuth phi (0 = straight back, positive towards the body's left) and
// relative height h in [-1, 1], pushed clear of the body by `clearance`.
Vector3f head_point(const BodyInfo& info, float phi, float h, float clearance) {
  const Vector3f& r = info.head_radii;
  const float s = std::sqrt(std::max(0.0f, 1 - h * h));
  const Vector3f dir(std::sin(phi), 0, -std::cos(phi));
  Vector3f p = info.head_center + Vector3f(r.x() * s * dir.x(), r.y() * h, r.z() * s * dir.z());
  info.push_out(p, clearance, (p - info.head_center).normalized());
  return p;
}

// === Per-kind layouts

// A ring garment (skirt, sleeve, coat tails): chains around an axis, flaring out by `flare`, with a band of height
// `band` above the root ring. `ring(theta)` gives the root point's offset from `center` (before the push-out);
// `axis` is the direction the chains hang; thetas are the chains' angles.
void ring_garment(const BodyInfo& info, PieceLayout& piece, const Vector3f& center, const Vector3f& axis,
                  const Vector3f& u, const Vector3f& v, float ru, float rv, const std::vector<float>& thetas, bool closed,
                  float length, int n, float flare, float radius, float clearance, float band, float band_offset,
                  float band_ru, float band_rv, float pleat_depth) {
  Sheet sheet;
  sheet.first = static_cast<int>(piece.chains.size());
  sheet.count = static_cast<int>(thetas.size());
  sheet.closed = closed;
  sheet.pleat_depth = pleat_depth;
  for (float th : thetas) {
    const Vector3f radial = (std::cos(th) * u + std::sin(th) * v).normalized();
    const Vector3f tangent = (-std::sin(th) * u + std::cos(th) * v).normalized();
    Vector3f root = center + ru * std::cos(th) * u + rv * std::sin(th) * v;
    info.push_out(root, radius + clearance, radial);
    const Vector3f dir0 = (std::cos(flare) * axis + std::sin(flare) * radial).normalized();
    piece.chains.push_back(grow_chain(info, root, dir0, length, n, 0.0f, radius, clearance, tangent));
    if (band > 0) {
      const Vector3f top = center - band * axis + (band_ru + band_offset) * std::cos(th) * u +
                           (band_rv + band_offset) * std::sin(th) * v;
      sheet.band_top.push_back(top);
    }
  }
  piece.sheets.push_back(sheet);
}

// Chain count that fits `bodies` bodies with n bones each, within [lo, hi].
int chains_for(int bodies, int n, int lo, int hi) {
  return std::clamp(bodies / std::max(1, n), lo, hi);
}

// forced_bones > 0: a topology's bone count instead of the one chosen from the skirt's length.
PieceLayout layout_skirt(const BodyInfo& info, ApparelKind kind, int bodies, float clearance, std::mt19937& rng,
                         int forced_bones) {
  PieceLayout piece;
  piece.kind = kind;
  piece.attach = kPelvis;
  piece.connected = true;
  const bool pleated = kind == ApparelKind::kPleatedSkirt;
  const float H = info.H;
  const float y_pelvis = info.joint(kPelvis).y(), y_spine1 = info.joint(kSpine1).y();
  const float y_top = lerp(y_pelvis, y_spine1, uniform(rng, 0.2f, 0.8f));
  const float band = uniform(rng, 0.025f, 0.045f) * H;
  const float y_root = y_top - band;
  const float thigh = (info.joint(kLeftHip) - info.joint(kLeftKnee)).norm();
  const float length =
      std::max(0.0f, y_root - info.joint(kLeftHip).y()) + thigh * (pleated ? uniform(rng, 0.6f, 1.1f)
                                                                            : uniform(rng, 0.65f, 1.2f));
  const int n = forced_bones > 0 ? forced_bones : length > 0.3f * H ? 5 : 4;
  const int count = chains_for(bodies, n, 8, 16);
  const float flare = (pleated ? uniform(rng, 10.0f, 20.0f) : uniform(rng, 22.0f, 36.0f)) * kDegrees;
  float a, b, zc, ta, tb, tzc;
  info.torso_section(y_root, 0.02f * H, &a, &b, &zc);
  info.torso_section(y_top, 0.02f * H, &ta, &tb, &tzc);
  const float seg = length / static_cast<float>(n);
  const float radius = std::clamp(0.28f * seg, 0.012f, 0.035f);
  std::vector<float> thetas;
  const float phase = uniform(rng, 0.0f, 1.0f);
  for (int i = 0; i < count; ++i) thetas.push_back(2 * kPi * (static_cast<float>(i) + phase) / static_cast<float>(count));
  // Ring around the vertical through the torso's centre: u along +Z (front), v along +X (left).
  ring_garment(info, piece, Vector3f(0, y_root, zc), Vector3f(0, -1, 0), Vector3f(0, 0, 1), Vector3f(1, 0, 0), b, a,
               thetas, true, length, n, flare, radius, clearance, band, 0.004f + clearance, tb, ta,
               pleated ? 0.006f * H / 1.7f + 0.15f * radius : 0.0f);
  piece.sheets.back().band_top.clear();
  for (float th : thetas)
    piece.sheets.back().band_top.push_back(Vector3f(0, y_top, tzc) + (tb + 0.004f + clearance) * std::cos(th) * Vector3f(0, 0, 1) +
                                           (ta + 0.004f + clearance) * std::sin(th) * Vector3f(1, 0, 0));
  piece.physics.mass = 0.06f;
  piece.physics.swing = (pleated ? 35.0f : 45.0f) * kDegrees;
  piece.physics.sway = 12 * kDegrees;
  piece.physics.ring_joints = true;
  return piece;
}

PieceLayout layout_coat_tails(const BodyInfo& info, int bodies, float clearance, std::mt19937& rng) {
  PieceLayout piece;
  piece.kind = ApparelKind::kCoatTails;
  piece.attach = kPelvis;
  piece.connected = true;
  const float H = info.H;
  const float y_top = info.joint(kSpine1).y();
  const float y_root = lerp(info.joint(kPelvis).y(), y_top, 0.3f);
  const float y_knee = info.joint(kLeftKnee).y();
  const float length = (y_root - y_knee) * uniform(rng, 0.75f, 1.05f);
  const int n = 4;
  const int per_flap = chains_for(bodies / 2, n, 2, 4);
  float a, b, zc, ta, tb, tzc;
  info.torso_section(y_root, 0.02f * H, &a, &b, &zc);
  info.torso_section(y_top, 0.02f * H, &ta, &tb, &tzc);
  const float seg = length / n;
  const float radius = std::clamp(0.28f * seg, 0.012f, 0.035f);
  const float flare = uniform(rng, 6.0f, 14.0f) * kDegrees;
  const float span = uniform(rng, 0.55f, 0.8f), split = 0.08f;
  for (int flap = 0; flap < 2; ++flap) {
    std::vector<float> thetas;
    for (int i = 0; i < per_flap; ++i) {
      const float t = static_cast<float>(i) / static_cast<float>(per_flap - 1);
      const float off = split + t * span;
      thetas.push_back(flap == 0 ? kPi - off : kPi + off);  // theta = pi is the back
    }
    if (flap == 0) std::reverse(thetas.begin(), thetas.end());
    ring_garment(info, piece, Vector3f(0, y_root, zc), Vector3f(0, -1, 0), Vector3f(0, 0, 1), Vector3f(1, 0, 0), b, a,
                 thetas, false, length, n, flare, radius, clearance, y_top - y_root, 0.004f + clearance, tb, ta, 0.0f);
    Sheet& s = piece.sheets.back();
    s.band_top.clear();
    for (float th : thetas)
      s.band_top.push_back(Vector3f(0, y_top, tzc) + (tb + 0.004f + clearance) * std::cos(th) * Vector3f(0, 0, 1) +
                           (ta + 0.004f + clearance) * std::sin(th) * Vector3f(1, 0, 0));
  }
  piece.physics.mass = 0.08f;
  piece.physics.swing = 40 * kDegrees;
  piece.physics.sway = 12 * kDegrees;
  piece.physics.ring_joints = true;
  return piece;
}

PieceLayout layout_sleeve(const BodyInfo& info, int side, int bodies, float clearance, std::mt19937& rng) {
  PieceLayout piece;
  piece.kind = ApparelKind::kSleeves;
  const int elbow = side == 0 ? kLeftElbow : kRightElbow, wrist = side == 0 ? kLeftWrist : kRightWrist;
  piece.attach = elbow;
  piece.connected = true;
  const Vector3f e = info.joint(elbow), w = info.joint(wrist);
  const float forearm = (w - e).norm();
  const Vector3f axis = (w - e).normalized();
  Vector3f u = Vector3f(0, 1, 0) - axis.y() * axis;
  if (u.squaredNorm() < 1e-6f) u = axis.unitOrthogonal();
  u.normalize();
  const Vector3f v = axis.cross(u);
  const Capsule& fore = info.capsules[info.joint_body[elbow]];
  const float band = 0.25f * forearm;
  const Vector3f root_center = e + band * axis;
  const float length = forearm * uniform(rng, 0.8f, 1.2f);
  const int n = 3;
  const int count = chains_for(bodies, n, 5, 8);
  const float seg = length / n;
  const float radius = std::clamp(0.3f * seg, 0.01f, 0.025f);
  std::vector<float> thetas;
  for (int i = 0; i < count; ++i) thetas.push_back(2 * kPi * static_cast<float>(i) / static_cast<float>(count));
  const float r = fore.r;
  ring_garment(info, piece, root_center, axis, u, v, r, r, thetas, true, length, n,
               uniform(rng, 12.0f, 25.0f) * kDegrees, radius, clearance, band, 0.004f + clearance, r - 0.004f - clearance,
               r - 0.004f - clearance, 0.0f);
  piece.physics.mass = 0.04f;
  piece.physics.swing = 35 * kDegrees;
  piece.physics.sway = 12 * kDegrees;
  piece.physics.stiffness = 1.5f;
  piece.physics.ring_joints = true;
  return piece;
}

PieceLayout layout_hair_sheet(const BodyInfo& info, int bodies, float clearance, std::mt19937& rng) {
  PieceLayout piece;
  piece.kind = ApparelKind::kHairSheet;
  piece.attach = kHead;
  const float length = info.head_h * uniform(rng, 1.3f, 2.8f);
  const int n = length > 2.0f * info.head_h ? 5 : 4;
  const int count = chains_for(bodies, n, 5, 10);
  const float seg = length / n;
  const float radius = std::clamp(0.25f * seg, 0.01f, 0.03f);
  const float span = uniform(rng, 60.0f, 85.0f) * kDegrees, h = uniform(rng, 0.05f, 0.4f);
  Sheet sheet;
  sheet.first = 0;
  sheet.count = count;
  for (int i = 0; i < count; ++i) {
    const float phi = -span + 2 * span * static_cast<float>(i) / static_cast<float>(count - 1);
    const Vector3f root = head_point(info, phi, h, radius + clearance);
    const Vector3f out(std::sin(phi), 0, -std::cos(phi));
    const Vector3f dir0 = (0.7f * out + Vector3f(0, -1, 0)).normalized();
    piece.chains.push_back(grow_chain(info, root, dir0, length, n, 1.0f, radius, clearance,
                                      Vector3f(std::cos(phi), 0, std::sin(phi))));
  }
  piece.sheets.push_back(sheet);
  piece.physics.mass = 0.04f;
  piece.physics.swing = 40 * kDegrees;
  piece.physics.sway = 15 * kDegrees;
  piece.physics.ring_joints = true;
  return piece;
}

PieceLayout layout_strands(const BodyInfo& info, ApparelKind kind, int bodies, float clearance, std::mt19937& rng) {
  PieceLayout piece;
  piece.kind = kind;
  piece.attach = kHead;
  const bool twin = kind == ApparelKind::kTwinTails;
  const float length = info.head_h * (twin ? uniform(rng, 1.5f, 3.0f) : uniform(rng, 1.2f, 2.6f));
  const int n = twin ? 5 : 4;
  const int count = twin ? 2 : chains_for(bodies, n, 3, 8);
  const float ry = info.head_radii.y();
  const float r0 = twin ? uniform(rng, 0.16f, 0.24f) * ry : 0.09f * ry, r1 = twin ? 0.05f * ry : 0.04f * ry;
  for (int i = 0; i < count; ++i) {
    float phi, h;
    Vector3f dir0;
    if (twin) {
      phi = (i == 0 ? 1.0f : -1.0f) * 105 * kDegrees;
      h = 0.55f;
      dir0 = Vector3f(i == 0 ? 1.0f : -1.0f, -0.4f, -0.3f).normalized();
    } else {
      phi = -110 * kDegrees + 220 * kDegrees * (static_cast<float>(i) + 0.5f) / static_cast<float>(count) +
            uniform(rng, -5.0f, 5.0f) * kDegrees;
      h = uniform(rng, 0.0f, 0.45f);
      dir0 = (0.6f * Vector3f(std::sin(phi), 0, -std::cos(phi)) + Vector3f(0, -1, 0)).normalized();
    }
    const float radius = std::max(r0 + 0.002f, 0.01f);
    const Vector3f root = head_point(info, phi, h, radius + clearance);
    Chain c = grow_chain(info, root, dir0, length, n, twin ? 0.8f : 1.0f, radius, clearance,
                         Vector3f(std::cos(phi), 0, std::sin(phi)));
    for (int k = 0; k < n; ++k)
      c.radii[k] = std::max(0.01f, lerp(r0, r1, (static_cast<float>(k) + 0.5f) / n) + 0.002f);
    piece.chains.push_back(c);
    piece.tubes.push_back(Tube{i, r0, r1});
  }
  piece.physics.mass = twin ? 0.06f : 0.03f;
  piece.physics.stiffness = twin ? 2.0f : 1.0f;
  piece.physics.swing = 40 * kDegrees;
  piece.physics.sway = 40 * kDegrees;
  return piece;
}

PieceLayout layout_cape(const BodyInfo& info, int bodies, float clearance, std::mt19937& rng) {
  PieceLayout piece;
  piece.kind = ApparelKind::kCape;
  piece.attach = kSpine3;
  const float H = info.H;
  const float y_sh = info.joint(kLeftShoulder).y();
  const float xs = info.joint(kLeftShoulder).x();
  const float length = (y_sh - info.joint(kLeftKnee).y()) * uniform(rng, 0.55f, 0.95f);
  const int n = 4;
  const int count = chains_for(bodies, n, 5, 9);
  const float seg = length / n;
  const float radius = std::clamp(0.25f * seg, 0.012f, 0.035f);
  const float width = uniform(rng, 0.6f, 0.85f) * xs;
  float a, b, zc;
  info.torso_section(y_sh - 0.04f * H, 0.02f * H, &a, &b, &zc);
  Sheet sheet;
  sheet.first = 0;
  sheet.count = count;
  for (int i = 0; i < count; ++i) {
    const float x = width - 2 * width * static_cast<float>(i) / static_cast<float>(count - 1);
    Vector3f root(x, y_sh + 0.01f * H, zc - b - radius - clearance);
    info.push_out(root, radius + clearance, Vector3f(0, 0, -1));
    const Vector3f dir0 = Vector3f(0.15f * x / std::max(width, 1e-3f), -1.0f, -0.25f).normalized();
    piece.chains.push_back(grow_chain(info, root, dir0, length, n, 1.0f, radius, clearance, Vector3f(-1, 0, 0)));
  }
  piece.sheets.push_back(sheet);
  piece.physics.mass = 0.08f;
  piece.physics.swing = 45 * kDegrees;
  piece.physics.sway = 12 * kDegrees;
  piece.physics.ring_joints = true;
  return piece;
}

PieceLayout layout_ribbons(const BodyInfo& info, int bodies, float clearance, std::mt19937& rng) {
  (void)bodies;
  PieceLayout piece;
  piece.kind = ApparelKind::kRibbons;
  const float H = info.H;
  const int where = uniform_int(rng, 0, 2);  // 0 a wrist, 1 the back of the head, 2 the back of the waist
  const int n = 4;
  const float width = uniform(rng, 0.018f, 0.03f) * H / 1.7f;
  Vector3f roots[2], dir0;
  float length;
  if (where == 0) {
    const int side = uniform_int(rng, 0, 1);
    const int wrist = side == 0 ? kLeftWrist : kRightWrist, elbow = side == 0 ? kLeftElbow : kRightElbow;
    piece.attach = wrist;
    const Vector3f w = info.joint(wrist), e = info.joint(elbow);
    const Vector3f along = (w - e).normalized();
    for (int i = 0; i < 2; ++i) roots[i] = w - (0.02f + 0.03f * i) * H * along + Vector3f(0, -0.02f * H, 0);
    dir0 = Vector3f(0, -1, -0.1f).normalized();
    length = H * uniform(rng, 0.1f, 0.18f);
  } else if (where == 1) {
    piece.attach = kHead;
    const float dx = 0.3f * info.head_radii.x();
    for (int i = 0; i < 2; ++i) roots[i] = head_point(info, (i == 0 ? 1 : -1) * 0.3f, 0.0f, 0.0f) + Vector3f(0, 0, 0);
    (void)dx;
    dir0 = Vector3f(0, -1, -0.4f).normalized();
    length = info.head_h * uniform(rng, 1.0f, 2.0f);
  } else {
    piece.attach = kPelvis;
    const float y = lerp(info.joint(kPelvis).y(), info.joint(kSpine1).y(), 0.5f);
    float a, b, zc;
    info.torso_section(y, 0.02f * H, &a, &b, &zc);
    for (int i = 0; i < 2; ++i) roots[i] = Vector3f((i == 0 ? 1 : -1) * 0.25f * a, y, zc - b);
    dir0 = Vector3f(0, -1, -0.3f).normalized();
    length = (y - info.joint(kLeftKnee).y()) * uniform(rng, 0.6f, 0.95f);
  }
  const float radius = std::clamp(0.25f * length / n, 0.01f, 0.025f);
  for (int i = 0; i < 2; ++i) {
    Vector3f root = roots[i];
    info.push_out(root, radius + clearance, dir0);
    piece.chains.push_back(grow_chain(info, root, dir0, length, n, 1.0f, radius, clearance, Vector3f(1, 0, 0)));
    Sheet s;
    s.first = i;
    s.count = 1;
    s.ribbon_width = width;
    piece.sheets.push_back(s);
  }
  piece.physics.mass = 0.02f;
  piece.physics.swing = 50 * kDegrees;
  piece.physics.sway = 30 * kDegrees;
  piece.physics.stiffness = 0.5f;
  return piece;
}

// === Mesh and skinning of a piece

// Skinning influences of a point at bone coordinate x of a chain: hat functions at the bones' middles, the
// attachment joint (rig bone `attach`) at the root.
void chain_influences(const Chain& c, int attach, float x, float scale, std::vector<std::pair<int, float>>& out) {
  const int n = c.num_bones();
  auto add = [&](int bone, float w) {
    if (w <= 0) return;
    for (auto& [b, v] : out)
      if (b == bone) {
        v += w;
        return;
      }
    out.emplace_back(bone, w);
  };
  if (x <= 0.5f) {
    add(attach, scale * (1 - 2 * x));
    add(c.first_bone, scale * 2 * x);
  } else if (x >= static_cast<float>(n) - 0.5f) {
    add(c.first_bone + n - 1, scale);
  } else {
    const int k = static_cast<int>(std::floor(x - 0.5f));
    const float f = x - 0.5f - static_cast<float>(k);
    add(c.first_bone + k, scale * (1 - f));
    add(c.first_bone + k + 1, scale * f);
  }
}

struct MeshBuilder {
  std::vector<Vector3f> V;
  std::vector<Eigen::Vector3i> F;
  std::vector<std::vector<std::pair<int, float>>> W;  // rig bone influences per vertex

  int add(const Vector3f& p, const std::vector<std::pair<int, float>>& w) {
    V.push_back(p);
    W.push_back(w);
    return static_cast<int>(V.size()) - 1;
  }
  void quad(int a, int b, int c, int d, bool flip) {  // a (i, j), b (i, j+1), c (i+1, j), d (i+1, j+1)
    if (!flip) {
      F.emplace_back(a, b, c);
      F.emplace_back(b, d, c);
    } else {
      F.emplace_back(a, c, b);
      F.emplace_back(b, c, d);
    }
  }
};

// Rows (along the chains) and columns of a grid of about `vertices` points over a `width` by `length` sheet.
void grid_size(int vertices, float width, float length, int min_rows, int min_cols, int* rows, int* cols) {
  const float aspect = std::max(width, 1e-3f) / std::max(length, 1e-3f);
  int c = static_cast<int>(std::lround(std::sqrt(std::max(1.0f, vertices * aspect))));
  c = std::max(c, min_cols);
  int r = std::max(min_rows, vertices / std::max(1, c) - 1);
  *rows = r;
  *cols = c;
}

// grid: in, a topology's rows and columns (0, 0: measure them); out, the ones used.
void build_sheet(const PieceLayout& piece, const Sheet& s, int vertices, float thickness, MeshBuilder& out,
                 Eigen::Vector2i& grid) {
  const auto& chains = piece.chains;
  const Chain& c0 = chains[s.first];
  const int n = c0.num_bones();
  // Width (mean distance between neighbouring chains along the sheet) and length.
  float width = s.ribbon_width, length = 0;
  for (int i = 0; i < s.count; ++i) length = std::max(length, chains[s.first + i].length());
  const int gaps = s.count == 1 ? 1 : (s.closed ? s.count : s.count - 1);
  if (s.count > 1) {
    width = 0;
    for (int i = 0; i < gaps; ++i) {
      const Chain& a = chains[s.first + i];
      const Chain& b = chains[s.first + (i + 1) % s.count];
      width += 0.5f * ((a.points.front() - b.points.front()).norm() + (a.points.back() - b.points.back()).norm());
    }
  }
  const int band_rows = s.band_top.empty() ? 0 : 2;
  int rows, cols;
  grid_size(vertices / 2, width, length, 2 * n, s.closed ? 2 * gaps : gaps + 1, &rows, &cols);
  if (grid.x() > 0) rows = grid.x(), cols = grid.y();
  grid = Eigen::Vector2i(rows, cols);
  const int per_gap = std::max(1, static_cast<int>(std::lround(static_cast<float>(cols - (s.closed ? 0 : 1)) / gaps)));
  const int M = s.closed ? per_gap * gaps : per_gap * gaps + 1;  // columns
  const int R = rows + band_rows;                                 // rows 0..R, the band first
  // Base positions, influences and pleat offsets on the grid.
  std::vector<Vector3f> P(static_cast<size_t>((R + 1) * M));
  std::vector<std::vector<std::pair<int, float>>> Wg(P.size());
  std::vector<float> pleat(P.size(), 0.0f);
  for (int j = 0; j < M; ++j) {
    const float cpar = static_cast<float>(j) / static_cast<float>(per_gap);
    int a = std::min(static_cast<int>(std::floor(cpar)), s.count - 1);
    float f = cpar - static_cast<float>(a);
    if (!s.closed && a == s.count - 1 && s.count > 1) {
      a = s.count - 2;
      f = 1.0f;
    }
    const int b = s.count == 1 ? a : (a + 1) % s.count;
    const Chain& ca = chains[s.first + a];
    const Chain& cb = chains[s.first + b];
    const float rib = s.count == 1 ? (static_cast<float>(j) / static_cast<float>(M - 1) - 0.5f) * s.ribbon_width : 0;
    // Pleats: a triangle wave with two folds per gap.
    const float wave = 1 - 4 * std::abs(std::fmod(2 * cpar + 0.25f, 1.0f) - 0.5f);
    for (int i = 0; i <= R; ++i) {
      const size_t g = static_cast<size_t>(i) * M + j;
      std::vector<std::pair<int, float>>& w = Wg[g];
      if (i < band_rows) {
        const float t = static_cast<float>(i) / static_cast<float>(band_rows);  // 0 at the band's top
        const Vector3f top = (1 - f) * s.band_top[a] + f * s.band_top[b];
        const Vector3f root = (1 - f) * ca.points[0] + f * cb.points[0];
        P[g] = (1 - t) * top + t * root;
        w.emplace_back(piece.attach, 1.0f);
        continue;
      }
      const float x = static_cast<float>(n) * static_cast<float>(i - band_rows) / static_cast<float>(rows);
      P[g] = (1 - f) * ca.at(x) + f * cb.at(x) + rib * ca.side_at(x);
      if (s.count == 1) {
        chain_influences(ca, piece.attach, x, 1.0f, w);
      } else {
        chain_influences(ca, piece.attach, x, 1 - f, w);
        chain_influences(cb, piece.attach, x, f, w);
      }
      pleat[g] = s.pleat_depth * wave * (0.3f + 0.7f * x / static_cast<float>(n));
    }
  }
  // Normals from the base grid, then two layers offset by +-thickness / 2 (plus the pleat).
  auto at = [&](int i, int j) -> const Vector3f& { return P[static_cast<size_t>(i) * M + j]; };
  std::vector<int> front(P.size()), back(P.size());
  for (int layer = 0; layer < 2; ++layer) {
    for (int i = 0; i <= R; ++i) {
      for (int j = 0; j < M; ++j) {
        const int jl = s.closed ? (j + M - 1) % M : std::max(j - 1, 0);
        const int jr = s.closed ? (j + 1) % M : std::min(j + 1, M - 1);
        const Vector3f dcol = at(i, jr) - at(i, jl);
        const Vector3f drow = at(std::min(i + 1, R), j) - at(std::max(i - 1, 0), j);
        Vector3f nrm = dcol.cross(drow);
        nrm = nrm.squaredNorm() > 1e-14f ? Vector3f(nrm.normalized()) : Vector3f::UnitZ();
        const size_t g = static_cast<size_t>(i) * M + j;
        const float off = pleat[g] + (layer == 0 ? 0.5f : -0.5f) * thickness;
        (layer == 0 ? front : back)[g] = out.add(P[g] + off * nrm, Wg[g]);
      }
    }
  }
  const int jmax = s.closed ? M : M - 1;
  for (int i = 0; i < R; ++i) {
    for (int j = 0; j < jmax; ++j) {
      const int j1 = (j + 1) % M;
      const size_t a = static_cast<size_t>(i) * M + j, b = static_cast<size_t>(i) * M + j1;
      const size_t c = static_cast<size_t>(i + 1) * M + j, d = static_cast<size_t>(i + 1) * M + j1;
      out.quad(front[a], front[b], front[c], front[d], false);
      out.quad(back[a], back[b], back[c], back[d], true);
    }
  }
}

void build_tube(const PieceLayout& piece, const Tube& t, int vertices, MeshBuilder& out) {
  const Chain& c = piece.chains[t.chain];
  const int n = c.num_bones();
  const int ring = std::clamp(vertices / 40, 6, 10);
  const int R = std::max(2 * n, vertices / ring - 1);
  std::vector<int> idx(static_cast<size_t>((R + 1) * ring));
  for (int i = 0; i <= R; ++i) {
    const float x = static_cast<float>(n) * static_cast<float>(i) / static_cast<float>(R);
    const Vector3f p = c.at(x);
    const float k = std::min(static_cast<int>(std::floor(x)), n - 1);
    const Vector3f tangent = (c.points[static_cast<int>(k) + 1] - c.points[static_cast<int>(k)]).normalized();
    Vector3f s = c.side_at(x);
    s = (s - s.dot(tangent) * tangent).normalized();
    const Vector3f b = tangent.cross(s);
    const float r = lerp(t.r0, t.r1, x / static_cast<float>(n));
    std::vector<std::pair<int, float>> w;
    chain_influences(c, piece.attach, x, 1.0f, w);
    for (int j = 0; j < ring; ++j) {
      const float phi = 2 * kPi * static_cast<float>(j) / static_cast<float>(ring);
      idx[static_cast<size_t>(i) * ring + j] = out.add(p + r * (std::cos(phi) * s + std::sin(phi) * b), w);
    }
  }
  for (int i = 0; i < R; ++i)
    for (int j = 0; j < ring; ++j) {
      const int j1 = (j + 1) % ring;
      out.quad(idx[i * ring + j], idx[i * ring + j1], idx[(i + 1) * ring + j], idx[(i + 1) * ring + j1], false);
    }
  std::vector<std::pair<int, float>> w0, w1;
  chain_influences(c, piece.attach, 0.0f, 1.0f, w0);
  chain_influences(c, piece.attach, static_cast<float>(n), 1.0f, w1);
  const int c0 = out.add(c.points.front(), w0), c1 = out.add(c.points.back(), w1);
  for (int j = 0; j < ring; ++j) {
    const int j1 = (j + 1) % ring;
    out.F.emplace_back(c0, idx[j1], idx[j]);
    out.F.emplace_back(c1, idx[R * ring + j], idx[R * ring + j1]);
  }
}

// === Rig of a piece

void add_piece_rig(PieceLayout& piece, int index, const BodyInfo& info, const ApparelOptions& options, PhysicsRig& rig) {
  const std::string prefix = detail::concat(apparel_kind_name(piece.kind), index);
  const ChainPhysics& ph = piece.physics;
  for (size_t ci = 0; ci < piece.chains.size(); ++ci) {
    Chain& c = piece.chains[ci];
    const int n = c.num_bones();
    c.first_bone = rig.num_bones();
    c.first_body = rig.num_bodies();
    for (int k = 0; k < n; ++k) {
      PhysicsBone bone;
      bone.name = detail::concat(prefix, "_c", ci, "_b", k);
      bone.parent = k == 0 ? piece.attach : c.first_bone + k - 1;
      bone.rest_position = c.points[k];
      rig.bones.push_back(bone);
      const Vector3f axis = c.points[k + 1] - c.points[k];
      const float len = axis.norm();
      PhysicsBody body;
      body.name = bone.name;
      body.bone = c.first_bone + k;
      const float r = std::min(c.radii[k], 0.45f * len);
      if (len > 2.2f * r) {
        body.shape = PhysicsShape::kCapsule;
        body.size = Vector3f(r, len - 2 * r, 0);
      } else {
        body.shape = PhysicsShape::kSphere;
        body.size = Vector3f(std::max(0.5f * len, 0.005f), 0, 0);
      }
      body.rest.position = 0.5f * (c.points[k] + c.points[k + 1]);
      body.rest.rotation = frame_rotation(axis, c.sides[k]);
      body.mass = ph.mass;
      body.linear_damping = std::clamp(ph.linear_damping * options.damping_scale, 0.0f, 1.0f);
      body.angular_damping = std::clamp(ph.angular_damping * options.damping_scale, 0.0f, 1.0f);
      body.friction = 0.2f;
      body.group = kApparelGroup;
      body.non_collision_mask = 1u << kApparelGroup;
      body.mode = PhysicsMode::kDynamic;
      rig.bodies.push_back(body);
    }
    for (int k = 0; k < n; ++k) {
      PhysicsJoint joint;
      joint.name = detail::concat(rig.bones[c.first_bone + k].name, "_joint");
      joint.body_a = k == 0 ? info.joint_body[piece.attach] : c.first_body + k - 1;
      joint.body_b = c.first_body + k;
      joint.rest.position = c.points[k];
      joint.rest.rotation = rig.bodies[c.first_body + k].rest.rotation;
      joint.angular_min = Vector3f(-ph.swing, -ph.twist, -ph.sway);
      joint.angular_max = Vector3f(ph.swing, ph.twist, ph.sway);
      // Spring stiffness from the gravity torque of the chain below the joint (bones k..n-1, centre of mass at
      // the middle of the rest), so that every joint sags by a similar angle.
      float below = 0;
      for (int m = k; m < n; ++m) below += (c.points[m + 1] - c.points[m]).norm();
      const float torque = static_cast<float>(n - k) * ph.mass * kGravity * 0.5f * below;
      const float stiffness = ph.stiffness * options.stiffness_scale * torque;
      joint.angular_stiffness = Vector3f(stiffness, stiffness, stiffness);
      rig.joints.push_back(joint);
    }
  }
  if (!ph.ring_joints) return;
  for (const Sheet& s : piece.sheets) {
    if (s.count < 2) continue;
    const int pairs = s.closed ? s.count : s.count - 1;
    for (int i = 0; i < pairs; ++i) {
      const Chain& a = piece.chains[s.first + i];
      const Chain& b = piece.chains[s.first + (i + 1) % s.count];
      for (int k = 0; k < std::min(a.num_bones(), b.num_bones()); ++k) {
        PhysicsJoint joint;
        joint.name = detail::concat(prefix, "_ring", s.first + i, "_", k);
        joint.body_a = a.first_body + k;
        joint.body_b = b.first_body + k;
        const Vector3f pa = rig.bodies[joint.body_a].rest.position, pb = rig.bodies[joint.body_b].rest.position;
        joint.rest.position = 0.5f * (pa + pb);
        joint.rest.rotation = rig.bodies[joint.body_a].rest.rotation;
        const float slack = 0.2f * (pb - pa).norm();
        joint.linear_min = Vector3f::Constant(-slack);
        joint.linear_max = Vector3f::Constant(slack);
        joint.angular_min = Vector3f::Constant(1.0f);  // min > max: free
        joint.angular_max = Vector3f::Constant(-1.0f);
        rig.joints.push_back(joint);
      }
    }
  }
}

// Kinds drawn for one character: distinct items, at most one skirt.
std::vector<ApparelKind> draw_items(const ApparelOptions& options, std::mt19937& rng) {
  std::vector<ApparelKind> pool = options.kinds;
  if (pool.empty())
    for (int k = 0; k < kApparelKindCount; ++k) pool.push_back(static_cast<ApparelKind>(k));
  std::sort(pool.begin(), pool.end());
  pool.erase(std::unique(pool.begin(), pool.end()), pool.end());
  const int count = uniform_int(rng, options.min_pieces, options.max_pieces);
  std::vector<ApparelKind> items;
  while (static_cast<int>(items.size()) < count && !pool.empty()) {
    const int pick = uniform_int(rng, 0, static_cast<int>(pool.size()) - 1);
    const ApparelKind kind = pool[pick];
    items.push_back(kind);
    pool.erase(pool.begin() + pick);
    if (kind == ApparelKind::kPleatedSkirt || kind == ApparelKind::kFlaredSkirt) {
      pool.erase(std::remove_if(pool.begin(), pool.end(),
                                [](ApparelKind k) {
                                  return k == ApparelKind::kPleatedSkirt || k == ApparelKind::kFlaredSkirt;
                                }),
                 pool.end());
    }
  }
  return items;
}

// Relative vertex share of an item (bigger garments get more).
float vertex_share(ApparelKind kind) {
  switch (kind) {
    case ApparelKind::kPleatedSkirt:
    case ApparelKind::kFlaredSkirt:
    case ApparelKind::kCape:
      return 1.5f;
    case ApparelKind::kHairSheet:
    case ApparelKind::kCoatTails:
      return 1.0f;
    case ApparelKind::kSleeves:
      return 0.8f;
    case ApparelKind::kHairStrands:
    case ApparelKind::kTwinTails:
      return 0.7f;
    case ApparelKind::kRibbons:
      return 0.4f;
  }
  return 1.0f;
}

// Bodies an item asks for relative to the others.
float body_share(ApparelKind kind) {
  switch (kind) {
    case ApparelKind::kPleatedSkirt:
    case ApparelKind::kFlaredSkirt:
      return 1.6f;
    case ApparelKind::kRibbons:
    case ApparelKind::kTwinTails:
      return 0.3f;
    default:
      return 1.0f;
  }
}

}  // namespace

// === Public API

const char* apparel_kind_name(ApparelKind kind) {
  switch (kind) {
    case ApparelKind::kPleatedSkirt:
      return "pleated_skirt";
    case ApparelKind::kFlaredSkirt:
      return "flared_skirt";
    case ApparelKind::kHairSheet:
      return "hair_sheet";
    case ApparelKind::kHairStrands:
      return "hair_strands";
    case ApparelKind::kTwinTails:
      return "twin_tails";
    case ApparelKind::kCape:
      return "cape";
    case ApparelKind::kSleeves:
      return "sleeves";
    case ApparelKind::kRibbons:
      return "ribbons";
    case ApparelKind::kCoatTails:
      return "coat_tails";
  }
  return "unknown";
}

void validate_apparel_options(const ApparelOptions& o) {
  AMT_CHECK(o.min_pieces >= 1 && o.min_pieces <= 6, "apparel options: min_pieces: expected 1 to 6, found ",
            o.min_pieces);
  AMT_CHECK(o.max_pieces >= o.min_pieces && o.max_pieces <= 6,
            "apparel options: max_pieces: expected min_pieces (", o.min_pieces, ") to 6, found ", o.max_pieces);
  for (ApparelKind k : o.kinds)
    AMT_CHECK(static_cast<int>(k) < kApparelKindCount, "apparel options: kinds: expected values 0 to ",
              kApparelKindCount - 1, ", found ", static_cast<int>(k));
  AMT_CHECK(std::isfinite(o.vertex_fraction) && o.vertex_fraction >= 0.05f && o.vertex_fraction <= 0.8f,
            "apparel options: vertex_fraction: expected a value in [0.05, 0.8], found ", o.vertex_fraction);
  AMT_CHECK(o.max_bodies >= 4, "apparel options: max_bodies: expected >= 4, found ", o.max_bodies);
  AMT_CHECK(std::isfinite(o.clearance) && o.clearance >= 0 && o.clearance < 0.1f,
            "apparel options: clearance: expected metres in [0, 0.1), found ", o.clearance);
  AMT_CHECK(std::isfinite(o.capsule_margin) && o.capsule_margin >= 0 && o.capsule_margin < 0.1f,
            "apparel options: capsule_margin: expected metres in [0, 0.1), found ", o.capsule_margin);
  AMT_CHECK(std::isfinite(o.stiffness_scale) && o.stiffness_scale > 0,
            "apparel options: stiffness_scale: expected a positive value, found ", o.stiffness_scale);
  AMT_CHECK(std::isfinite(o.damping_scale) && o.damping_scale > 0,
            "apparel options: damping_scale: expected a positive value, found ", o.damping_scale);
  AMT_CHECK(std::isfinite(o.physics_variation) && o.physics_variation >= 0 && o.physics_variation <= 4,
            "apparel options: physics_variation: expected a value in [0, 4], found ", o.physics_variation);
}

std::vector<PhysicsBody> body_collision_capsules(const GeneratedBody& body, float margin,
                                                 std::vector<int32_t>* joint_body) {
  AMT_CHECK(std::isfinite(margin) && margin >= 0, "body_collision_capsules: margin: expected metres >= 0, found ",
            margin);
  const BodyInfo info = measure_body(body, margin);
  std::vector<PhysicsBody> bodies;
  for (size_t i = 0; i < info.capsules.size(); ++i)
    bodies.push_back(capsule_body(info.capsules[i],
                                  detail::concat(canonical_joint_names()[info.capsules[i].joint], "_collider", i)));
  if (joint_body) *joint_body = info.joint_body;
  return bodies;
}

DressedCharacter dress_character(const GeneratedBody& body, uint64_t seed, const ApparelOptions& options) {
  validate_apparel_options(options);
  std::seed_seq seq{static_cast<uint32_t>(seed), static_cast<uint32_t>(seed >> 32), 0x61707061u};
  std::mt19937 rng(seq);
  const std::vector<ApparelKind> items = draw_items(options, rng);
  return dress_character_with(body, items, seed ^ 0x9e3779b97f4a7c15ull, options);
}

DressedCharacter dress_character_with(const GeneratedBody& body, const std::vector<ApparelKind>& items, uint64_t seed,
                                      const ApparelOptions& options) {
  validate_apparel_options(options);
  AMT_CHECK(!items.empty(), "dress_character: expected at least one apparel item, found none");
  for (ApparelKind k : items)
    AMT_CHECK(static_cast<int>(k) < kApparelKindCount, "dress_character: items: expected kinds 0 to ",
              kApparelKindCount - 1, ", found ", static_cast<int>(k));
  const BodyInfo info = measure_body(body, options.capsule_margin);
  std::seed_seq seq{static_cast<uint32_t>(seed), static_cast<uint32_t>(seed >> 32), 0x64726573u};
  std::mt19937 rng(seq);

  // Budgets: vertices and bodies shared between the items.
  const int body_vertices = body.mesh.num_vertices();
  const ApparelTopology& topology = options.topology;
  const int budget_vertices = topology.empty() ? body_vertices : topology.body_vertices;
  const float apparel_vertices = options.vertex_fraction / (1 - options.vertex_fraction) * budget_vertices;
  float vshare = 0, bshare = 0;
  for (ApparelKind k : items) {
    vshare += vertex_share(k);
    bshare += body_share(k);
  }
  std::vector<PieceLayout> pieces;
  for (ApparelKind kind : items) {
    const int vb = std::max(60, static_cast<int>(apparel_vertices * vertex_share(kind) / vshare));
    const int bb = std::max(4, static_cast<int>(options.max_bodies * body_share(kind) / bshare));
    const float cl = options.clearance;
    switch (kind) {
      case ApparelKind::kPleatedSkirt:
      case ApparelKind::kFlaredSkirt:
        pieces.push_back(layout_skirt(info, kind, bb, cl, rng,
                                      topology.bones.size() > pieces.size() ? topology.bones[pieces.size()] : 0));
        break;
      case ApparelKind::kHairSheet:
        pieces.push_back(layout_hair_sheet(info, bb, cl, rng));
        break;
      case ApparelKind::kHairStrands:
      case ApparelKind::kTwinTails:
        pieces.push_back(layout_strands(info, kind, bb, cl, rng));
        break;
      case ApparelKind::kCape:
        pieces.push_back(layout_cape(info, bb, cl, rng));
        break;
      case ApparelKind::kSleeves:
        for (int side = 0; side < 2; ++side) {
          pieces.push_back(layout_sleeve(info, side, bb / 2, cl, rng));
          pieces.back().vertex_budget = vb / 2;
        }
        continue;
      case ApparelKind::kRibbons:
        pieces.push_back(layout_ribbons(info, bb, cl, rng));
        break;
      case ApparelKind::kCoatTails:
        pieces.push_back(layout_coat_tails(info, bb, cl, rng));
        break;
    }
    pieces.back().vertex_budget = vb;
  }
  ApparelTopology out_topology;
  // The bones per chain before the trim: this body's, or the topology's (which every kind but the skirts, whose
  // count is forced above, chooses from the seed alone).
  out_topology.body_vertices = budget_vertices;
  for (size_t p = 0; p < pieces.size(); ++p) {
    const int n = pieces[p].chains.front().num_bones();
    AMT_CHECK(topology.empty() || (topology.bones.size() == pieces.size() && topology.bones[p] == n),
              "dress_character: topology: expected ", topology.bones.size(), " pieces with the template's bones (",
              topology.bones.size() > p ? topology.bones[p] : -1, " for piece ", p, "), found ", pieces.size(),
              " pieces, ", n, " bones (a template of another seed or options?)");
    out_topology.bones.push_back(n);
  }
  // Trim chains' bones when the pieces together exceed the body cap (keeps at least 2 bones per chain).
  auto total_bodies = [&]() {
    int t = 0;
    for (const PieceLayout& p : pieces)
      for (const Chain& c : p.chains) t += c.num_bones();
    return t;
  };
  while (total_bodies() > options.max_bodies) {
    bool trimmed = false;
    for (PieceLayout& p : pieces) {
      for (Chain& c : p.chains) {
        if (c.num_bones() <= 2) continue;
        // Merge the last two bones: drop the second-to-last point.
        c.points.erase(c.points.end() - 2);
        c.sides.erase(c.sides.end() - 2);
        c.radii.pop_back();
        trimmed = true;
      }
      if (total_bodies() <= options.max_bodies) break;
    }
    if (!trimmed) break;
  }

  // Per-piece physics (ApparelOptions::physics_variation): a stream of its own, so that the layout above and
  // every dressing with the option off stay as they were.
  if (options.physics_variation > 0) {
    std::seed_seq physics_seq{static_cast<uint32_t>(seed), static_cast<uint32_t>(seed >> 32), 0x70687973u};
    std::mt19937 physics_rng(physics_seq);
    const float spread = std::log1p(options.physics_variation);
    const auto factor = [&] { return std::exp(uniform(physics_rng, -spread, spread)); };
    for (PieceLayout& piece : pieces) {
      ChainPhysics& ph = piece.physics;
      ph.mass *= factor();
      const float damping = factor();
      ph.linear_damping = std::min(ph.linear_damping * damping, 1.0f);
      ph.angular_damping = std::min(ph.angular_damping * damping, 1.0f);
      ph.stiffness *= factor();
      const float limits = factor();  // MMD rigs range from locked to loose joints
      ph.swing = std::min(ph.swing * limits, 80 * kDegrees);
      ph.sway = std::min(ph.sway * limits, 80 * kDegrees);
    }
  }

  DressedCharacter out;
  out.body = body;
  out.joint_body = info.joint_body;
  // Rig: canonical bones, their collision capsules, then the pieces.
  PhysicsRig& rig = out.rig;
  for (int j = 0; j < kCanonicalJointCount; ++j) {
    PhysicsBone b;
    b.name = body.skeleton.names[j];
    b.parent = body.skeleton.parents[j];
    b.rest_position = info.joint(j);
    rig.bones.push_back(b);
  }
  for (size_t i = 0; i < info.capsules.size(); ++i)
    rig.bodies.push_back(
        capsule_body(info.capsules[i], detail::concat(body.skeleton.names[info.capsules[i].joint], "_collider", i)));
  for (size_t p = 0; p < pieces.size(); ++p) add_piece_rig(pieces[p], static_cast<int>(p), info, options, rig);

  // Meshes.
  MeshBuilder mb;
  std::vector<int> piece_of_vertex;
  for (size_t p = 0; p < pieces.size(); ++p) {
    const PieceLayout& piece = pieces[p];
    const int first = static_cast<int>(mb.V.size());
    const int parts = static_cast<int>(piece.sheets.size() + piece.tubes.size());
    const int per_part = std::max(40, piece.vertex_budget / std::max(1, parts));
    const float thickness = 0.003f;
    for (const Sheet& s : piece.sheets) {
      const size_t k = out_topology.sheets.size();
      AMT_CHECK(topology.empty() || k < topology.sheets.size(), "dress_character: topology: expected ",
                topology.sheets.size(), " sheets, found more");
      Eigen::Vector2i grid = topology.empty() ? Eigen::Vector2i(0, 0) : topology.sheets[k];
      build_sheet(piece, s, per_part, thickness, mb, grid);
      out_topology.sheets.push_back(grid);
    }
    for (const Tube& t : piece.tubes) build_tube(piece, t, per_part, mb);
    piece_of_vertex.resize(mb.V.size(), static_cast<int>(p));
    ApparelPiece ap;
    ap.kind = piece.kind;
    ap.connected_to_body = piece.connected;
    ap.attachment_joint = piece.attach;
    for (const Chain& c : piece.chains) {
      ap.chain_roots.push_back(c.first_bone);
      ap.chain_length =
          std::max(ap.chain_length, (c.points.front() - info.joint(piece.attach)).norm() + c.length());
    }
    ap.first_vertex = body_vertices + first;
    ap.end_vertex = body_vertices + static_cast<int>(mb.V.size());
    out.pieces.push_back(ap);
  }

  AMT_CHECK(topology.empty() || out_topology.sheets.size() == topology.sheets.size(),
            "dress_character: topology: expected ", topology.sheets.size(), " sheets, found ", out_topology.sheets.size());
  out.topology = std::move(out_topology);
  const int na = static_cast<int>(mb.V.size());
  const int N = body_vertices + na;
  out.mesh.V.resize(N, 3);
  out.mesh.F.resize(body.mesh.num_faces() + static_cast<int>(mb.F.size()), 3);
  out.mesh.V.topRows(body_vertices) = body.mesh.V;
  out.mesh.F.topRows(body.mesh.num_faces()) = body.mesh.F;
  for (int i = 0; i < na; ++i) out.mesh.V.row(body_vertices + i) = mb.V[i].transpose();
  for (size_t f = 0; f < mb.F.size(); ++f)
    out.mesh.F.row(body.mesh.num_faces() + static_cast<int>(f)) = (mb.F[f].array() + body_vertices).transpose();

  // Skinning: body vertices keep their weights; apparel vertices their influences (at most 4 by construction).
  out.rig_weights.indices.setZero(N, kMaxInfluences);
  out.rig_weights.weights.setZero(N, kMaxInfluences);
  out.rig_weights.indices.topRows(body_vertices) = body.weights.indices;
  out.rig_weights.weights.topRows(body_vertices) = body.weights.weights;
  out.apparel_mask.assign(static_cast<size_t>(N), 0);
  out.vertex_piece.assign(static_cast<size_t>(N), -1);
  out.body_weights = MatrixXfR::Zero(N, kCanonicalJointCount);
  const MatrixXfR body_dense = densify_weights(body.weights, kCanonicalJointCount);
  out.body_weights.topRows(body_vertices) = body_dense;
  for (int i = 0; i < na; ++i) {
    const int v = body_vertices + i;
    auto w = mb.W[i];
    std::sort(w.begin(), w.end(), [](const auto& x, const auto& y) {
      return x.second > y.second || (x.second == y.second && x.first < y.first);
    });
    AMT_CHECK(static_cast<int>(w.size()) <= kMaxInfluences, "dress_character: internal: ", w.size(), " influences");
    float sum = 0;
    for (const auto& [b, x] : w) sum += x;
    bool apparel = false;
    for (size_t k = 0; k < w.size(); ++k) {
      out.rig_weights.indices(v, static_cast<int>(k)) = w[k].first;
      out.rig_weights.weights(v, static_cast<int>(k)) = w[k].second / sum;
      if (w[k].first >= kCanonicalJointCount && w[k].second > 0) apparel = true;
    }
    const PieceLayout& piece = pieces[piece_of_vertex[i]];
    if (!apparel) {
      for (size_t k = 0; k < w.size(); ++k) out.body_weights(v, w[k].first) += w[k].second / sum;
      continue;
    }
    out.apparel_mask[v] = 1;
    out.vertex_piece[v] = piece_of_vertex[i];
    if (piece.connected) {
      // The nearest body vertex's weights: what a plain skinning pipeline would give the garment.
      int best = 0;
      float best_d = std::numeric_limits<float>::infinity();
      for (int b = 0; b < body_vertices; ++b) {
        const float d = (body.mesh.V.row(b) - out.mesh.V.row(v)).squaredNorm();
        if (d < best_d) {
          best_d = d;
          best = b;
        }
      }
      out.body_weights.row(v) = body_dense.row(best);
    } else {
      out.body_weights(v, piece.attach) = 1.0f;
    }
  }
  validate_physics_rig(out.rig, "dress_character");
  return out;
}

Rig DressedCharacter::dataset_rig() const {
  Rig r;
  for (const PhysicsBone& b : rig.bones) {
    r.bone_names.push_back(b.name);
    r.bone_parents.push_back(b.parent);
    r.rest_transforms.push_back(make_transform(Matrix3f::Identity(), b.rest_position));
  }
  r.skin_indices = rig_weights.indices;
  r.skin_weights = rig_weights.weights;
  return r;
}

CharacterData DressedCharacter::character_data(const std::string& name, const std::string& split) const {
  CharacterData c;
  c.name = name;
  c.mesh = mesh;
  c.skeleton = body.skeleton;
  c.apparel_mask = apparel_mask;
  c.body_weights = body_weights;
  c.rig = dataset_rig();
  c.split = split;
  return c;
}

int DressedCharacter::num_apparel_bodies() const {
  int n = 0;
  for (const PhysicsBody& b : rig.bodies) n += b.mode != PhysicsMode::kFollowBone ? 1 : 0;
  return n;
}

}  // namespace amt
