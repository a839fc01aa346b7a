#include "data_tools/garment/body_penetration.h"

#include <cmath>
#include <optional>

#include "data_tools/geometry/error.h"
#include "data_tools/geometry/winding_number.h"

namespace amt {
namespace {

// Winding numbers closer than this to 0.5 are settled by a tree built on the pose (see measure()).
constexpr double kUnsureBand = 0.05;

}  // namespace

BodyPenetration::BodyPenetration(const MatrixX3f& V, const MatrixX3i& F, const std::vector<uint8_t>& apparel_mask) {
  const Eigen::Index N = V.rows();
  AMT_CHECK(static_cast<Eigen::Index>(apparel_mask.size()) == N, "body penetration: apparel mask: expected ", N,
            " entries (one per vertex), found ", apparel_mask.size());
  std::vector<int32_t> body_index(static_cast<size_t>(N), -1);
  for (Eigen::Index i = 0; i < N; ++i) {
    if (apparel_mask[i]) {
      apparel_.push_back(static_cast<int32_t>(i));
    } else {
      body_index[i] = static_cast<int32_t>(body_.size());
      body_.push_back(static_cast<int32_t>(i));
    }
  }
  std::vector<int32_t> faces;
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    for (int k = 0; k < 3; ++k)
      AMT_CHECK(F(f, k) >= 0 && F(f, k) < N, "body penetration: faces: expected vertex indices in [0, ", N,
                "), found ", F(f, k), " in face ", f);
    const int32_t a = body_index[F(f, 0)], b = body_index[F(f, 1)], c = body_index[F(f, 2)];
    if (a >= 0 && b >= 0 && c >= 0) faces.insert(faces.end(), {a, b, c});
  }
  body_faces_ = Eigen::Map<const MatrixX3i>(faces.data(), static_cast<Eigen::Index>(faces.size() / 3), 3);
  body_pose_.resize(static_cast<Eigen::Index>(body_.size()), 3);
  apparel_pose_.resize(static_cast<Eigen::Index>(apparel_.size()), 3);
  if (apparel_.empty() || body_faces_.rows() == 0) return;
  for (size_t k = 0; k < body_.size(); ++k) body_pose_.row(k) = V.row(body_[k]);
  tree_ = std::make_unique<WindingNumberTree>(body_pose_, body_faces_);
}

BodyPenetration::~BodyPenetration() = default;
BodyPenetration::BodyPenetration(BodyPenetration&&) noexcept = default;
BodyPenetration& BodyPenetration::operator=(BodyPenetration&&) noexcept = default;

std::optional<Penetration> BodyPenetration::measure(const MatrixX3f& P) {
  AMT_CHECK(P.rows() == static_cast<Eigen::Index>(apparel_.size() + body_.size()), "body penetration: pose: expected ",
            apparel_.size() + body_.size(), " vertices, found ", P.rows());
  if (!tree_) return std::nullopt;
  for (size_t k = 0; k < body_.size(); ++k) body_pose_.row(k) = P.row(body_[k]);
  if (!body_pose_.allFinite()) return std::nullopt;  // refit would throw; a fresh tree too
  tree_->refit(body_pose_);
  for (size_t k = 0; k < apparel_.size(); ++k) apparel_pose_.row(k) = P.row(apparel_[k]);
  // Per apparel vertex its depth, or -1 outside; -2 for a verdict that the refitted tree's far field
  // could decide (winding number within kUnsureBand of 0.5): a tree built on this pose decides those.
  const Eigen::Index n = apparel_pose_.rows();
  std::vector<float> depth(static_cast<size_t>(n), -1.0f);
#pragma omp parallel for schedule(dynamic, 64)
  for (Eigen::Index i = 0; i < n; ++i) {
    const Eigen::Vector3f p = apparel_pose_.row(i).transpose();
    const double w = tree_->winding_number(p);
    if (std::abs(w - 0.5) < kUnsureBand)
      depth[i] = -2.0f;
    else if (w > 0.5)
      depth[i] = tree_->distance(p);
  }
  std::optional<WindingNumberTree> fresh;
  for (Eigen::Index i = 0; i < n; ++i) {
    if (depth[i] != -2.0f) continue;
    if (!fresh) fresh.emplace(body_pose_, body_faces_);
    const Eigen::Vector3f p = apparel_pose_.row(i).transpose();
    depth[i] = fresh->inside(p) ? tree_->distance(p) : -1.0f;
  }
  // Summed in point order: the same sum for any thread count.
  Penetration out;
  out.total = static_cast<int>(n);
  for (const float d : depth) {
    if (d < 0) continue;
    ++out.inside;
    out.depth_sum_cm += 100.0 * d;
  }
  return out;
}

}  // namespace amt
