#include "refit/garment_fit.h"

#include "data_tools/geometry/error.h"
#include <chrono>
#include <memory>

#include "refit/curve_shape.h"
#include "refit/fit_term.h"
#include "refit/positional.h"
#include "refit/surface_shape.h"
#include "refit/triangle_intersections.h"

namespace amt::refit {

NewtonResult fit_garment(const Positions& source, const MatrixX3i& F_garment, const Positions& start,
                         const Positions& avatar_V, const MatrixX3i& avatar_F, const Positions& source_joints,
                         const Positions& target_joints, const MatrixX2i& bones, Positions* garment,
                         const GarmentFitOptions& options, const std::function<void(const NewtonStep&)>& observer,
                         GarmentFitReport* report) {
  const int n_g = static_cast<int>(source.rows()), n_a = static_cast<int>(avatar_V.rows());
  AMT_CHECK(start.rows() == n_g, "garment fit: ", start.rows(), " start positions for a garment of ", n_g,
            " vertices");
  const CollisionMesh mesh = make_garment_avatar_mesh(source, F_garment, avatar_V, avatar_F);
  Positions x(n_g + n_a, 3);
  x << start, avatar_V;
  const std::vector<uint8_t>& fixed = mesh.vertex_obstacle;  // the avatar stays where it is
  check_garment_avatar_start(mesh, x, static_cast<int>(F_garment.rows()), "garment fit", "the avatar's");

  const SurfaceShapeTerm surface(source, F_garment, options.weights.surface_weight);
  const CurveShapeTerm curve(source, F_garment, options.weights.curve_weight);
  PositionalTerm positional(source, F_garment, source_joints, bones, options.weights.positional_weight);
  positional.set_skeleton(target_joints);
  const BarrierPotential potential(mesh, options.weights.d_hat, options.weights.contact_weight);
  const BarrierObjective contact(potential);
  std::vector<const Objective*> terms = {&surface, &curve, &positional, &contact};
  // Eq. 7's w_fit L_fit, on the avatar's distance field (now a closed shape of its own, section 3.6).
  std::unique_ptr<AvatarDistanceField> field;
  std::unique_ptr<FitTerm> fit;
  double field_seconds = 0.0;
  if (!options.fit_vertices.empty()) {
    const auto start_time = std::chrono::steady_clock::now();
    field = std::make_unique<AvatarDistanceField>(avatar_V, avatar_F, options.voxel_size, options.field_band);
    field_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_time).count();
    fit = std::make_unique<FitTerm>(*field, source, F_garment, options.fit_vertices, options.weights.fit_weight);
    terms.push_back(fit.get());
  }
  const NewtonResult result = projected_newton(terms, &mesh, fixed, &x, options.newton, observer);
  *garment = x.topRows(n_g);
  if (report) {
    report->newton = result;
    report->fit_distance = fit ? fit->mean_fit_distance(x) : 0.0;
    report->field_seconds = field_seconds;
  }
  return result;
}

}  // namespace amt::refit
