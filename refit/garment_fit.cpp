#include "refit/garment_fit.h"

#include "data_tools/geometry/error.h"
#include "refit/curve_shape.h"
#include "refit/positional.h"
#include "refit/surface_shape.h"
#include "refit/triangle_intersections.h"

namespace amt::refit {

NewtonResult fit_garment(const Positions& source, const MatrixX3i& F_garment, const Positions& start,
                         const Positions& avatar_V, const MatrixX3i& avatar_F, const Positions& source_joints,
                         const Positions& target_joints, const MatrixX2i& bones, Positions* garment,
                         const GarmentFitOptions& options, const std::function<void(const NewtonStep&)>& observer) {
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
  const NewtonResult result =
      projected_newton({&surface, &curve, &positional, &contact}, &mesh, fixed, &x, options.newton, observer);
  *garment = x.topRows(n_g);
  return result;
}

}  // namespace amt::refit
