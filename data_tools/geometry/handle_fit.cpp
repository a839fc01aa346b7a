#include "data_tools/geometry/handle_fit.h"

#include <Eigen/SVD>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>

#include "data_tools/geometry/error.h"

namespace amt {

struct HandleFit::Solver {
  Eigen::SparseMatrix<double> W;  // N_a by H
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> normal;
};

HandleFit::HandleFit(const MatrixX3f& V, HandleSkin skin)
    : skin_(std::move(skin)), solver_(std::make_unique<Solver>()) {
  const int64_t N = V.rows(), Na = int64_t(skin_.vertices.size()), H = skin_.num_handles();
  AMT_CHECK(skin_.handles.rows() == Na && skin_.weights.rows() == Na && skin_.handles.cols() == skin_.weights.cols(),
            "handle skin: expected ", Na, " rows of handles and weights of one width, found ", skin_.handles.rows(),
            " by ", skin_.handles.cols(), " and ", skin_.weights.rows(), " by ", skin_.weights.cols());
  AMT_CHECK(H > 0 || Na == 0, "handle skin: expected handles for ", Na, " vertices, found none");
  AMT_CHECK(skin_.rest.allFinite(), "handle skin: rest: expected finite handle positions");
  rest_.resize(Na, 3);
  std::vector<Eigen::Triplet<double>> entries;
  for (int64_t r = 0; r < Na; ++r) {
    const int32_t v = skin_.vertices[size_t(r)];
    AMT_CHECK(v >= 0 && v < N, "handle skin: vertices: expected indices in [0, ", N, "), found ", v);
    rest_.row(r) = V.row(v);
    double sum = 0;
    for (Eigen::Index k = 0; k < skin_.weights.cols(); ++k) {
      const float w = skin_.weights(r, k);
      AMT_CHECK(std::isfinite(w) && w >= 0.0f, "handle skin: weights: expected finite non-negative weights, found ", w,
                " at vertex ", v);
      if (w == 0.0f) continue;
      const int32_t h = skin_.handles(r, k);
      AMT_CHECK(h >= 0 && h < H, "handle skin: handles: expected indices in [0, ", H, "), found ", h, " at vertex ", v);
      sum += w;
    }
    AMT_CHECK(sum > 0, "handle skin: weights: expected a positive weight at every vertex, found none at vertex ", v);
    skin_.weights.row(r) /= float(sum);
    for (Eigen::Index k = 0; k < skin_.weights.cols(); ++k) {
      if (skin_.weights(r, k) > 0) entries.emplace_back(int(r), int(skin_.handles(r, k)), double(skin_.weights(r, k)));
    }
  }
  solver_->W.resize(Na, H);
  solver_->W.setFromTriplets(entries.begin(), entries.end());
  if (H == 0) return;
  Eigen::SparseMatrix<double> A = Eigen::SparseMatrix<double>(solver_->W.transpose()) * solver_->W;
  // A handle no vertex weighs would make the normal matrix singular: a tiny ridge keeps it at its least-norm
  // position, which the fallback then ignores (no vertex moves with it).
  const double ridge = 1e-9 * std::max(1.0, A.diagonal().maxCoeff());
  for (int64_t h = 0; h < H; ++h) A.coeffRef(h, h) += ridge;
  solver_->normal.compute(A);
  AMT_CHECK(solver_->normal.info() == Eigen::Success, "handle skin: expected a solvable least-squares fit, found ",
            "a singular normal matrix");
}

HandleFit::~HandleFit() = default;
HandleFit::HandleFit(HandleFit&&) noexcept = default;
HandleFit& HandleFit::operator=(HandleFit&&) noexcept = default;

void HandleFit::kabsch(const MatrixX3f& Y, const Quaternions& fallback, Quaternions& rotations) const {
  const int64_t Na = rest_.rows(), H = skin_.num_handles();
  AMT_CHECK(fallback.size() == size_t(H), "handle fit: expected ", H, " fallback rotations, found ", fallback.size());
  // 1. Weighted Kabsch per handle.
  std::vector<Eigen::Matrix3d> cov(static_cast<size_t>(H), Eigen::Matrix3d::Zero());
  std::vector<Eigen::Vector3d> rest_sum(size_t(H), Eigen::Vector3d::Zero()),
      target_sum(size_t(H), Eigen::Vector3d::Zero());
  std::vector<double> mass(size_t(H), 0.0);
  for (int64_t r = 0; r < Na; ++r) {
    const Eigen::Vector3d p = rest_.row(r).transpose().cast<double>();
    const Eigen::Vector3d y = Y.row(skin_.vertices[size_t(r)]).transpose().cast<double>();
    for (Eigen::Index k = 0; k < skin_.weights.cols(); ++k) {
      const double w = skin_.weights(r, k);
      if (w == 0) continue;
      const size_t h = size_t(skin_.handles(r, k));
      mass[h] += w, rest_sum[h] += w * p, target_sum[h] += w * y;
      cov[h] += w * p * y.transpose();
    }
  }
  rotations.resize(size_t(H));
  for (int64_t h = 0; h < H; ++h) {
    const size_t i = size_t(h);
    rotations[i] = fallback[i];
    if (mass[i] <= 0) continue;
    const Eigen::Vector3d pc = rest_sum[i] / mass[i], yc = target_sum[i] / mass[i];
    const Eigen::Matrix3d S = cov[i] - mass[i] * pc * yc.transpose();  // sum w (p - pc)(y - yc)^T
    const Eigen::JacobiSVD<Eigen::Matrix3d> svd(S, Eigen::ComputeFullU | Eigen::ComputeFullV);
    const Eigen::Vector3d sigma = svd.singularValues();
    if (!(sigma(0) > 0) || sigma(1) < 1e-6 * sigma(0)) continue;
    Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
    D(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0 ? -1.0 : 1.0;
    const Eigen::Matrix3d R = svd.matrixV() * D * svd.matrixU().transpose();
    rotations[i] = Eigen::Quaternionf(Eigen::Quaterniond(R).normalized().cast<float>());
  }
}

double HandleFit::positions_for(const MatrixX3f& Y, const Quaternions& rotations, MatrixX3f& positions) const {
  const int64_t Na = rest_.rows(), H = skin_.num_handles();
  // Positions by least squares: W t = y - sum_k w_k R_k (p - c_k).
  Eigen::MatrixXd rhs(Na, 3);
  std::vector<Eigen::Matrix3d> R(static_cast<size_t>(H));
  for (int64_t h = 0; h < H; ++h) R[size_t(h)] = rotations[size_t(h)].toRotationMatrix().cast<double>();
  for (int64_t r = 0; r < Na; ++r) {
    const Eigen::Vector3d p = rest_.row(r).transpose().cast<double>();
    Eigen::Vector3d x = Y.row(skin_.vertices[size_t(r)]).transpose().cast<double>();
    for (Eigen::Index k = 0; k < skin_.weights.cols(); ++k) {
      const double w = skin_.weights(r, k);
      if (w == 0) continue;
      const int32_t h = skin_.handles(r, k);
      x -= w * (R[size_t(h)] * (p - skin_.rest.row(h).transpose().cast<double>()));
    }
    rhs.row(r) = x.transpose();
  }
  positions.resize(H, 3);
  if (H == 0) return 0.0;
  const Eigen::MatrixXd t = solver_->normal.solve(Eigen::MatrixXd(solver_->W.transpose() * rhs));
  positions = t.cast<float>();
  return (solver_->W * t - rhs).squaredNorm();
}

void HandleFit::fit(const MatrixX3f& Y, const Quaternions& fallback, Quaternions& rotations,
                    MatrixX3f& positions) const {
  AMT_CHECK(fallback.size() == size_t(skin_.num_handles()), "handle fit: expected ", skin_.num_handles(),
            " fallback rotations, found ", fallback.size());
  kabsch(Y, fallback, rotations);
  const double own = positions_for(Y, rotations, positions);
  MatrixX3f anchored;
  const double carried = positions_for(Y, fallback, anchored);
  if (carried < own) rotations = fallback, positions = anchored;
}

void HandleFit::skin_vertices(const Quaternions& rotations, const MatrixX3f& positions, MatrixX3f& X) const {
  const int64_t Na = rest_.rows(), H = skin_.num_handles();
  AMT_CHECK(rotations.size() == size_t(H) && positions.rows() == H, "handle skin: expected ", H,
            " rotations and positions, found ", rotations.size(), " and ", positions.rows());
  std::vector<Eigen::Matrix3f> R(static_cast<size_t>(H));
  for (int64_t h = 0; h < H; ++h) R[size_t(h)] = rotations[size_t(h)].toRotationMatrix();
  for (int64_t r = 0; r < Na; ++r) {
    const Eigen::Vector3f p = rest_.row(r).transpose();
    Eigen::Vector3f x = Eigen::Vector3f::Zero();
    for (Eigen::Index k = 0; k < skin_.weights.cols(); ++k) {
      const float w = skin_.weights(r, k);
      if (w == 0.0f) continue;
      const int32_t h = skin_.handles(r, k);
      x += w * (R[size_t(h)] * (p - skin_.rest.row(h).transpose()) + positions.row(h).transpose());
    }
    X.row(skin_.vertices[size_t(r)]) = x.transpose();
  }
}

// === FitError

namespace {
constexpr double kBinWidth = 1e-5;  // metres (0.01 mm)
constexpr size_t kBins = 100000;    // up to 1 m
}  // namespace

FitError::FitError() : bins_(kBins + 1, 0) {}

void FitError::add(const MatrixX3f& A, const MatrixX3f& B, const std::vector<int32_t>& rows) {
  AMT_CHECK(A.rows() == B.rows(), "fit error: expected two frames of the same size, found ", A.rows(), " and ",
            B.rows());
  auto one = [&](Eigen::Index i) {
    const double d = double((A.row(i) - B.row(i)).norm());
    const size_t bin = std::isfinite(d) ? std::min(kBins, size_t(d / kBinWidth)) : kBins;
    ++bins_[bin], ++count_;
    max_ = std::max(max_, std::isfinite(d) ? d : HUGE_VAL);
  };
  if (rows.empty()) {
    for (Eigen::Index i = 0; i < A.rows(); ++i) one(i);
  } else {
    for (const int32_t i : rows) one(i);
  }
}

double FitError::quantile(double q) const {
  if (count_ == 0) return 0.0;
  const int64_t rank = std::min<int64_t>(count_ - 1, int64_t(std::ceil(q * double(count_))) - 1);
  int64_t seen = 0;
  for (size_t b = 0; b < bins_.size(); ++b) {
    seen += bins_[b];
    if (seen > std::max<int64_t>(rank, 0)) return std::min(max_, (double(b) + 1.0) * kBinWidth);
  }
  return max_;
}

}  // namespace amt
