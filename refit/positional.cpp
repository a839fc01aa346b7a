#include "refit/positional.h"

#include <algorithm>
#include <map>

#include "data_tools/geometry/error.h"
#include "data_tools/geometry/mesh.h"
#include "refit/assembly.h"
#include "refit/jet.h"
#include "refit/skeleton_shrink.h"

namespace amt::refit {

PositionalTerm::PositionalTerm(const Positions& source, const MatrixX3i& F, const Positions& source_joints,
                               const MatrixX2i& bones, double weight)
    : bones_(bones) {
  // Boundary edges: used by one face only.
  std::map<std::pair<int, int>, int> uses;
  for (int f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int a = F(f, k), b = F(f, (k + 1) % 3);
      ++uses[{std::min(a, b), std::max(a, b)}];
    }
  std::vector<uint8_t> on_boundary(source.rows(), 0);
  for (const auto& [edge, count] : uses)
    if (count == 1) on_boundary[edge.first] = on_boundary[edge.second] = 1;
  const MatrixX2i E = unique_edges(F);
  std::vector<double> length_sum(source.rows(), 0.0);
  std::vector<int> degree(source.rows(), 0);
  for (int e = 0; e < E.rows(); ++e) {
    const double l = (source.row(E(e, 0)) - source.row(E(e, 1))).norm();
    for (int k = 0; k < 2; ++k) length_sum[E(e, k)] += l, ++degree[E(e, k)];
  }
  Positions boundary_points;
  for (int v = 0; v < source.rows(); ++v)
    if (on_boundary[v]) vertices_.push_back(v);
  boundary_points.resize(static_cast<int>(vertices_.size()), 3);
  for (size_t i = 0; i < vertices_.size(); ++i) boundary_points.row(i) = source.row(vertices_[i]);
  joints_ = source_joints;
  set_skeleton(source_joints);
  bone_ = vertices_.empty() ? std::vector<int>() : nearest_bones(boundary_points, source_joints, bones);
  for (size_t i = 0; i < vertices_.size(); ++i) {
    const int v = vertices_[i], b = bone_[i];
    const Eigen::RowVector3d a = source_joints.row(bones(b, 0)), e = source_joints.row(bones(b, 1)) - a;
    source_u_.push_back((source.row(v) - a).dot(e) / e.squaredNorm());
    weight_.push_back(weight * length_sum[v] / degree[v]);
  }
}

void PositionalTerm::set_skeleton(const Positions& joints) {
  AMT_CHECK(joints.rows() == joints_.rows(), "positional term: a skeleton of ", joints.rows(), " joints, expected ",
            joints_.rows());
  for (int b = 0; b < bones_.rows(); ++b)
    AMT_CHECK((joints.row(bones_(b, 0)) - joints.row(bones_(b, 1))).squaredNorm() > 0.0, "positional term: bone ", b,
              " has zero length");
  joints_ = joints;
}

double PositionalTerm::value(const Positions& x) const { return derivatives(x, nullptr, nullptr); }

double PositionalTerm::derivatives(const Positions& x, Eigen::VectorXd* gradient,
                                   std::vector<Eigen::Triplet<double>>* hessian) const {
  double energy = 0.0;
  for (size_t i = 0; i < vertices_.size(); ++i) {
    const int v = vertices_[i], b = bone_[i];
    const Eigen::RowVector3d a = joints_.row(bones_(b, 0)), e = joints_.row(bones_(b, 1)) - a;
    const Eigen::Vector3d du = (e / e.squaredNorm()).transpose();  // ∇u: u is linear in v
    const double r = source_u_[i] - (x.row(v) - a).dot(e) / e.squaredNorm();
    energy += weight_[i] * r * r;
    if (gradient) gradient->segment<3>(3 * v) -= 2.0 * weight_[i] * r * du;
    if (hessian) {
      const Eigen::Matrix3d H = 2.0 * weight_[i] * du * du.transpose();  // exact, and PSD
      for (int p = 0; p < 3; ++p)
        for (int q = 0; q < 3; ++q) hessian->emplace_back(3 * v + p, 3 * v + q, H(p, q));
    }
  }
  return energy;
}

double PositionalTerm::inflation_derivatives(const Positions& x, const Positions& joints_at_t,
                                             const Positions& dt_joints, Eigen::VectorXd* gradient_x,
                                             double* gradient_t, std::vector<Eigen::Matrix4d>* blocks) const {
  double energy = 0.0;
  for (size_t i = 0; i < vertices_.size(); ++i) {
    const int v = vertices_[i], b = bone_[i];
    // Unknowns (v_x, v_y, v_z, t) at the current values; the bone's ends move linearly with t.
    const Jet<4> vx = Jet<4>::variable(x(v, 0), 0), vy = Jet<4>::variable(x(v, 1), 1), vz = Jet<4>::variable(x(v, 2), 2);
    const Jet<4> t = Jet<4>::variable(0.0, 3);  // t enters as the offset from the current skeleton
    auto moving = [&](int joint, int k) { return Jet<4>(joints_at_t(joint, k)) + dt_joints(joint, k) * t; };
    const Vec3<Jet<4>> a = {moving(bones_(b, 0), 0), moving(bones_(b, 0), 1), moving(bones_(b, 0), 2)};
    const Vec3<Jet<4>> c = {moving(bones_(b, 1), 0), moving(bones_(b, 1), 1), moving(bones_(b, 1), 2)};
    const Vec3<Jet<4>> e = c - a, p = Vec3<Jet<4>>{vx, vy, vz} - a;
    const Jet<4> r = Jet<4>(source_u_[i]) - dot(p, e) * reciprocal(dot(e, e));
    const Jet<4> l = weight_[i] * (r * r);
    energy += l.v;
    if (gradient_x) gradient_x->segment<3>(3 * v) += l.g.head<3>();
    if (gradient_t) *gradient_t += l.g[3];
    if (blocks) {
      Eigen::MatrixXd H = l.h;
      project_to_psd(H);
      blocks->push_back(H);
    }
  }
  return energy;
}

}  // namespace amt::refit
