#include "data_tools/formats/render.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "data_tools/formats/atomic_file.h"
#include "data_tools/geometry/error.h"

#define STB_IMAGE_WRITE_STATIC
#define STB_IMAGE_WRITE_IMPLEMENTATION
#include <stb/stb_image_write.h>

namespace amt {
namespace {

constexpr float kPi = 3.14159265358979f;
// Supersampling factor per axis: faces are rasterised at this multiple of the output size and averaged down,
// which smooths silhouettes at the cost of 4x the fill work (a few milliseconds for a thumbnail).
constexpr int kSupersample = 2;

uint8_t to_byte(float value) { return static_cast<uint8_t>(std::lround(std::clamp(value, 0.0f, 1.0f) * 255.0f)); }

void append_png_bytes(void* context, void* data, int size) {
  auto* out = static_cast<std::string*>(context);
  out->append(static_cast<const char*>(data), static_cast<size_t>(size));
}

}  // namespace

// === Images

void write_png(const Image& image, const std::string& path) {
  AMT_CHECK(image.width > 0 && image.height > 0, path, ": image: expected a non-empty image, found "
                                                     , image.width, " x ", image.height);
  AMT_CHECK(image.rgb.size() == static_cast<size_t>(image.width) * image.height * 3,
            path, ": image: expected ", image.width * image.height * 3, " bytes, found ", image.rgb.size());
  std::string bytes;
  const int ok = stbi_write_png_to_func(append_png_bytes, &bytes, image.width, image.height, 3, image.rgb.data(),
                                        image.width * 3);
  AMT_CHECK(ok != 0, path, ": PNG encoding failed");
  write_file_atomically(path, bytes);
}

Image image_grid(const std::vector<Image>& images, int columns, int padding, const Eigen::Vector3f& background) {
  AMT_CHECK(!images.empty(), "image_grid: expected at least one image");
  AMT_CHECK(columns >= 1, "image_grid: columns: expected >= 1, found ", columns);
  AMT_CHECK(padding >= 0, "image_grid: padding: expected >= 0, found ", padding);
  int cell_width = 0, cell_height = 0;
  for (const Image& image : images) {
    cell_width = std::max(cell_width, image.width);
    cell_height = std::max(cell_height, image.height);
  }
  const int count = static_cast<int>(images.size());
  const int cols = std::min(columns, count);
  const int rows = (count + cols - 1) / cols;
  Image grid;
  grid.width = cols * cell_width + (cols + 1) * padding;
  grid.height = rows * cell_height + (rows + 1) * padding;
  grid.rgb.resize(static_cast<size_t>(grid.width) * grid.height * 3);
  const uint8_t bg[3] = {to_byte(background.x()), to_byte(background.y()), to_byte(background.z())};
  for (size_t i = 0; i < grid.rgb.size(); ++i) grid.rgb[i] = bg[i % 3];
  for (int k = 0; k < count; ++k) {
    const Image& image = images[k];
    const int x0 = padding + (k % cols) * (cell_width + padding) + (cell_width - image.width) / 2;
    const int y0 = padding + (k / cols) * (cell_height + padding) + (cell_height - image.height) / 2;
    for (int y = 0; y < image.height; ++y) {
      std::copy_n(image.rgb.begin() + static_cast<ptrdiff_t>(y) * image.width * 3, image.width * 3,
                  grid.rgb.begin() + (static_cast<ptrdiff_t>(y0 + y) * grid.width + x0) * 3);
    }
  }
  return grid;
}

// === Rendering

Image render_mesh(const MatrixX3f& V, const MatrixX3i& F, const MatrixX3f& colors, const RenderOptions& options) {
  validate_mesh(TriMesh{V, F}, "render_mesh");
  AMT_CHECK(colors.rows() == V.rows(),
            "render_mesh: colors: expected ", V.rows(), " rows (one per vertex), found ", colors.rows());
  AMT_CHECK(options.width >= 8 && options.height >= 8,
            "render_mesh: image size: expected at least 8 x 8, found ", options.width, " x ", options.height);
  AMT_CHECK(std::isfinite(options.world_height) && options.world_height >= 0.0f,
            "render_mesh: world_height: expected >= 0, found ", options.world_height);

  // View space: x right, y up, z towards the viewer; p_view = Rx(pitch) Ry(-yaw) p.
  const float yaw = options.yaw_degrees * kPi / 180.0f, pitch = options.pitch_degrees * kPi / 180.0f;
  const Eigen::Matrix3f view = (Eigen::AngleAxisf(pitch, Eigen::Vector3f::UnitX()) *
                                Eigen::AngleAxisf(-yaw, Eigen::Vector3f::UnitY()))
                                   .toRotationMatrix();
  const MatrixX3f P = V * view.transpose();

  const int width = options.width * kSupersample, height = options.height * kSupersample;
  const Eigen::Vector3f lo = P.colwise().minCoeff(), hi = P.colwise().maxCoeff();
  const float usable_w = width * (1.0f - 2.0f * options.margin), usable_h = height * (1.0f - 2.0f * options.margin);
  float scale = 0.0f, cx = 0.0f, cy = 0.0f;  // screen = (cx + s x, cy - s y)
  if (options.world_height > 0.0f) {
    scale = usable_h / options.world_height;
    cx = width * 0.5f - scale * 0.5f * (lo.x() + hi.x());
    cy = height * (1.0f - options.margin);  // the floor's origin on the bottom margin
  } else {
    const Eigen::Vector3f extent = (hi - lo).cwiseMax(1e-6f);
    scale = std::min(usable_w / extent.x(), usable_h / extent.y());
    cx = width * 0.5f - scale * 0.5f * (lo.x() + hi.x());
    cy = height * 0.5f + scale * 0.5f * (lo.y() + hi.y());
  }

  std::vector<float> depth(static_cast<size_t>(width) * height, -std::numeric_limits<float>::infinity());
  std::vector<Eigen::Vector3f> color(static_cast<size_t>(width) * height, options.background);
  const Eigen::Vector3f light = options.light.normalized();
  for (int f = 0; f < F.rows(); ++f) {
    Eigen::Vector3f p[3];
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3f q = P.row(F(f, k)).transpose();
      p[k] = Eigen::Vector3f(cx + scale * q.x(), cy - scale * q.y(), q.z());
    }
    const Eigen::Vector3f normal = (P.row(F(f, 1)) - P.row(F(f, 0))).cross(P.row(F(f, 2)) - P.row(F(f, 0)));
    const float norm = normal.norm();
    if (!(norm > 0.0f)) continue;  // degenerate face
    const float lambert = std::abs(normal.dot(light)) / norm;  // two-sided
    const Eigen::Vector3f base = (colors.row(F(f, 0)) + colors.row(F(f, 1)) + colors.row(F(f, 2))).transpose() / 3.0f;
    const Eigen::Vector3f shaded = base * (options.ambient + (1.0f - options.ambient) * lambert);

    const float area = (p[1].x() - p[0].x()) * (p[2].y() - p[0].y()) - (p[2].x() - p[0].x()) * (p[1].y() - p[0].y());
    if (std::abs(area) < 1e-12f) continue;
    const int x_min = std::max(0, static_cast<int>(std::floor(std::min({p[0].x(), p[1].x(), p[2].x()}))));
    const int x_max = std::min(width - 1, static_cast<int>(std::ceil(std::max({p[0].x(), p[1].x(), p[2].x()}))));
    const int y_min = std::max(0, static_cast<int>(std::floor(std::min({p[0].y(), p[1].y(), p[2].y()}))));
    const int y_max = std::min(height - 1, static_cast<int>(std::ceil(std::max({p[0].y(), p[1].y(), p[2].y()}))));
    for (int y = y_min; y <= y_max; ++y) {
      for (int x = x_min; x <= x_max; ++x) {
        const float px = x + 0.5f, py = y + 0.5f;
        // Barycentric coordinates from the edge functions, normalised by the signed area (either winding).
        const float w0 = ((p[1].x() - px) * (p[2].y() - py) - (p[2].x() - px) * (p[1].y() - py)) / area;
        const float w1 = ((p[2].x() - px) * (p[0].y() - py) - (p[0].x() - px) * (p[2].y() - py)) / area;
        const float w2 = 1.0f - w0 - w1;
        if (w0 < 0.0f || w1 < 0.0f || w2 < 0.0f) continue;
        const float z = w0 * p[0].z() + w1 * p[1].z() + w2 * p[2].z();
        const size_t i = static_cast<size_t>(y) * width + x;
        if (z > depth[i]) {
          depth[i] = z;
          color[i] = shaded;
        }
      }
    }
  }

  Image image;
  image.width = options.width;
  image.height = options.height;
  image.rgb.resize(static_cast<size_t>(image.width) * image.height * 3);
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      Eigen::Vector3f sum = Eigen::Vector3f::Zero();
      for (int dy = 0; dy < kSupersample; ++dy)
        for (int dx = 0; dx < kSupersample; ++dx)
          sum += color[static_cast<size_t>(y * kSupersample + dy) * width + x * kSupersample + dx];
      sum /= static_cast<float>(kSupersample * kSupersample);
      for (int c = 0; c < 3; ++c) image.rgb[(static_cast<size_t>(y) * image.width + x) * 3 + c] = to_byte(sum[c]);
    }
  }
  return image;
}

MatrixX3f character_colors(int num_vertices, const std::vector<uint8_t>& apparel_mask) {
  AMT_CHECK(apparel_mask.empty() || static_cast<int>(apparel_mask.size()) == num_vertices,
            "character_colors: apparel_mask: expected ", num_vertices, " entries, found ", apparel_mask.size());
  const Eigen::RowVector3f skin(0.96f, 0.80f, 0.69f), cloth(0.30f, 0.45f, 0.85f);
  MatrixX3f colors(num_vertices, 3);
  for (int i = 0; i < num_vertices; ++i) colors.row(i) = !apparel_mask.empty() && apparel_mask[i] ? cloth : skin;
  return colors;
}

Image render_character(const TriMesh& mesh, const std::vector<uint8_t>& apparel_mask, const RenderOptions& options) {
  return render_mesh(mesh.V, mesh.F, character_colors(mesh.num_vertices(), apparel_mask), options);
}

}  // namespace amt
