#include "refit/garment_refit.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "data_tools/geometry/error.h"
#include "refit/aabb_tree.h"
#include "refit/distance_field.h"
#include "refit/fit_term.h"
#include "refit/garment_fit.h"
#include "refit/inflation.h"
#include "refit/skeleton_shrink.h"
#include "refit/surface_shape.h"
#include "refit/triangle_intersections.h"

namespace amt::refit {
namespace {

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

void check_finite(const Positions& x, const std::string& name, const char* field) {
  for (int v = 0; v < x.rows(); ++v)
    AMT_CHECK(x.row(v).allFinite(), name, ": ", field, " ", v, " is (", x(v, 0), ", ", x(v, 1), ", ", x(v, 2),
              "), expected finite coordinates");
}

void check_mesh(const RiggedMesh& m, const std::string& name) {
  AMT_CHECK(m.V.rows() > 0 && m.F.rows() > 0, name, ": mesh: ", m.V.rows(), " vertices and ", m.F.rows(),
            " faces, expected a triangle mesh");
  check_finite(m.V, name, "vertex");
  check_finite(m.joints, name, "joint");
  for (int f = 0; f < m.F.rows(); ++f)
    for (int k = 0; k < 3; ++k)
      AMT_CHECK(m.F(f, k) >= 0 && m.F(f, k) < m.V.rows(), name, ": face ", f, " has vertex ", m.F(f, k),
                ", expected 0 to ", m.V.rows() - 1);
}

// The smallest distance of the garment's pairs at x, over pairs within `range` (+inf when none).
double min_distance(const CollisionMesh& mesh, const Positions& x, double range) {
  return std::sqrt(min_distance_sq(mesh, x, proximity_candidates(mesh, x, range)));
}

}  // namespace

GarmentRefitResult refit_garment(const Positions& garment, const MatrixX3i& garment_F, const RiggedMesh& source,
                                 const RiggedMesh& target, const std::vector<int32_t>& parents,
                                 const GarmentRefitOptions& options,
                                 const std::function<void(const GarmentRefitProgress&)>& progress,
                                 const std::string& garment_name, const std::string& source_name,
                                 const std::string& target_name) {
  // === Input
  check_mesh({garment, garment_F, Positions(0, 3)}, garment_name);
  for (int f = 0; f < garment_F.rows(); ++f) {
    const Eigen::RowVector3d a = garment.row(garment_F(f, 0)), b = garment.row(garment_F(f, 1)),
                             c = garment.row(garment_F(f, 2));
    // Zero area against the longest side: a repeated vertex or three points on a line.
    const double longest = std::max({(b - a).squaredNorm(), (c - b).squaredNorm(), (a - c).squaredNorm()});
    AMT_CHECK((b - a).cross(c - a).squaredNorm() > 1e-12 * longest * longest, garment_name, ": face ", f, " (vertices ",
              garment_F(f, 0), ", ", garment_F(f, 1), ", ", garment_F(f, 2),
              ") is degenerate, expected a triangle of non-zero area");
  }
  check_mesh(source, source_name);
  check_mesh(target, target_name);
  const int num_joints = static_cast<int>(parents.size());
  AMT_CHECK(source.joints.rows() == num_joints, source_name, ": skeleton: ", source.joints.rows(), " joints, expected ",
            num_joints, " (the target's)");
  AMT_CHECK(target.joints.rows() == num_joints, target_name, ": skeleton: ", target.joints.rows(), " joints, expected ",
            num_joints, " (the source's)");
  const MatrixX2i bones = skeleton_bones(parents);
  AMT_CHECK(bones.rows() > 0, source_name, ": skeleton: no bones, expected at least one joint with a parent");
  for (int b = 0; b < bones.rows(); ++b)
    for (const auto& [m, name] : {std::make_pair(&source, &source_name), std::make_pair(&target, &target_name)})
      AMT_CHECK((m->joints.row(bones(b, 0)) - m->joints.row(bones(b, 1))).norm() > 1e-6, *name, ": skeleton: bone ", b,
                " (joints ", bones(b, 0), " to ", bones(b, 1), ") has zero length, expected a bone of positive length");
  // The shape term checks the garment's faces (degenerate, non-manifold) and measures the distortion.
  const SurfaceShapeTerm shape = [&] {
    try {
      return SurfaceShapeTerm(garment, garment_F, 1.0);
    } catch (const Error& e) {
      fail(garment_name, ": ", e.what());
    }
  }();
  {
    const CollisionMesh mesh = make_garment_avatar_mesh(garment, garment_F, source.V, source.F);
    Positions x(mesh.num_vertices, 3);
    x << garment, source.V;
    check_garment_avatar_start(mesh, x, static_cast<int>(garment_F.rows()), garment_name + " on " + source_name,
                               "the source avatar's");
  }
  GarmentRefitResult result;

  // === G_fit on the source avatar (section 3.4.4)
  auto start = std::chrono::steady_clock::now();
  std::vector<uint8_t> fit;
  if (options.fit_region_distance > 0 && options.weights.fit_weight > 0) {
    const AvatarDistanceField source_field(source.V, source.F, options.voxel_size, options.field_band);
    fit = fit_region(garment, source_field, options.fit_region_distance);
    const FitTerm source_fit(source_field, garment, garment_F, fit);
    result.fit_vertices = static_cast<int>(source_fit.vertices().size());
    result.source_fit_distance = source_fit.mean_fit_distance(garment);
  }

  // === Step 1: skeleton shrink (section 3.3)
  const ShrunkAvatar shrunk = shrink_to_skeleton(target.V, target.F, target.joints, source.joints, bones,
                                                 nearest_bones(target.V, target.joints, bones));
  result.shrunk_vertices = static_cast<int>(shrunk.shrunk.rows());
  result.shrink_seconds = seconds_since(start);

  // === Step 2: inflation (section 3.5)
  start = std::chrono::steady_clock::now();
  InflationOptions inflation_options;
  inflation_options.weights = options.weights;
  inflation_options.max_outer_iterations = options.max_outer_iterations;
  inflation_options.newton = options.newton;
  const InflationResult inflated =
      inflate_avatar(garment, garment_F, shrunk, source.joints, target.joints, bones, inflation_options,
                     [&](const InflationProgress& p) {
                       if (progress)
                         progress({"inflation", p.outer_iteration, p.t, p.energy, p.min_distance, p.newton_iterations});
                     });
  result.outer_iterations = inflated.outer_iterations;
  result.inflation_seconds = seconds_since(start);
  AMT_CHECK(inflated.snapped, target_name, ": the inflation stopped at t = ", inflated.t, " after ",
            inflated.outer_iterations, " outer iterations (", inflated.stop_reason,
            "), expected t = 1: the garment could not make room for the target avatar");

  // === Step 3: garment fit (section 3.6)
  start = std::chrono::steady_clock::now();
  GarmentFitOptions fit_options;
  fit_options.weights = options.weights;
  fit_options.newton = options.newton;
  fit_options.fit_vertices = fit;
  fit_options.voxel_size = options.voxel_size;
  fit_options.field_band = options.field_band;
  GarmentFitReport report;
  int step = 0;
  fit_garment(
      garment, garment_F, inflated.garment, target.V, target.F, source.joints, target.joints, bones, &result.garment,
      fit_options,
      [&](const NewtonStep& s) {
        if (progress)
          progress(
              {"fit", step++, 1.0, s.energy, min_distance(*s.collisions, *s.after, 10 * options.weights.d_hat), 0});
      },
      &report);
  result.fit_seconds = seconds_since(start);
  result.fit_iterations = report.newton.iterations;
  result.fit_stop_reason = report.newton.stop_reason;
  result.fit_distance = report.fit_distance;

  // === Report
  const std::vector<double> distortion = shape.pair_distortion(result.garment);
  double sum = 0.0;
  for (double d : distortion) {
    sum += d;
    result.distortion_max = std::max(result.distortion_max, std::sqrt(d));
  }
  result.distortion_rms = distortion.empty() ? 0.0 : std::sqrt(sum / double(distortion.size()));
  const CollisionMesh mesh = make_garment_avatar_mesh(garment, garment_F, target.V, target.F);
  Positions x(mesh.num_vertices, 3);
  x << result.garment, target.V;
  result.min_distance = min_distance(mesh, x, 0.02);
  // A static check of the result, independent of the CCD that kept every step intersection-free.
  result.crossing_pairs = static_cast<int>(crossing_triangle_pairs(mesh, x, 0).size());
  return result;
}

// By hand: a nearest-vertex query over a few thousand points is one AABB-tree query per vertex, and the
// refit library keeps to Eigen (no nanoflann).
SparseWeights transfer_weights(const Positions& garment, const Positions& avatar_V,
                               const SparseWeights& avatar_weights) {
  AMT_CHECK(avatar_weights.num_vertices() == avatar_V.rows(), "weight transfer: ", avatar_weights.num_vertices(),
            " weight rows for an avatar of ", avatar_V.rows(), " vertices");
  AMT_CHECK(avatar_V.rows() > 0, "weight transfer: the avatar has no vertices");
  std::vector<Aabb> boxes(avatar_V.rows());
  for (int v = 0; v < avatar_V.rows(); ++v) boxes[v].extend(avatar_V.row(v).transpose());
  const AabbTree tree(boxes);
  SparseWeights out;
  out.indices.resize(garment.rows(), kMaxInfluences);
  out.weights.resize(garment.rows(), kMaxInfluences);
  std::vector<int> hits;
  for (int g = 0; g < garment.rows(); ++g) {
    int best = -1;
    double best_d2 = std::numeric_limits<double>::infinity();
    for (double r = 0.01; best < 0; r *= 2) {  // grow the search box until it holds a vertex
      Aabb box;
      box.extend(garment.row(g).transpose());
      box.inflate(r);
      hits.clear();
      tree.query(box, &hits);
      for (int v : hits) {
        const double d2 = (avatar_V.row(v) - garment.row(g)).squaredNorm();
        if (d2 < best_d2 && d2 <= r * r) best_d2 = d2, best = v;  // within r: no vertex outside the box is nearer
      }
    }
    out.indices.row(g) = avatar_weights.indices.row(best);
    out.weights.row(g) = avatar_weights.weights.row(best);
  }
  return out;
}

}  // namespace amt::refit
