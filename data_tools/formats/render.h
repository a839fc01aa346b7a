#pragma once
// Pictures of characters for reports and the README: a small software rasterizer (orthographic camera,
// z-buffer, flat Lambert shading, two-sided faces so that thin apparel sheets show from both sides) and
// PNG output through stb_image_write.
//
// Written by hand because nothing in Debian renders a triangle mesh to an image without a display or a
// GPU context (OpenGL needs one; OSMesa and the ray tracers are large dependencies for a thumbnail).
#include <cstdint>
#include <string>
#include <vector>

#include "data_tools/geometry/mesh.h"

namespace amt {

// === Images

/// An 8-bit RGB image, rows top to bottom: rgb[3 * (y * width + x) + c].
struct Image {
  int width = 0;
  int height = 0;
  std::vector<uint8_t> rgb;
};

/// Encodes `image` as PNG and writes it to `path` (a temporary name, then renamed). Throws amt::Error
/// for an empty image or a file that cannot be written.
void write_png(const Image& image, const std::string& path);

/// Tiles `images` left to right, top to bottom, `columns` per row (>= 1), each in a cell as large as the
/// largest image, separated by `padding` pixels of `background`. Throws amt::Error for no images.
Image image_grid(const std::vector<Image>& images, int columns, int padding = 4,
                 const Eigen::Vector3f& background = Eigen::Vector3f(1.0f, 1.0f, 1.0f));

// === Rendering

/// Camera and shading of render_mesh.
struct RenderOptions {
  /// Image size in pixels (each >= 8).
  int width = 256;
  int height = 384;
  /// Rotation of the view about the vertical axis, degrees: 0 looks at the character's front (from +Z),
  /// 30 shows three quarters of the front and the character's left side.
  float yaw_degrees = 30.0f;
  /// Tilt of the view, degrees: positive looks down on the character.
  float pitch_degrees = 10.0f;
  /// Metres visible from the bottom to the top of the image with the floor (y = 0) at the bottom margin,
  /// so that characters rendered with the same value show their relative heights. 0 fits the mesh.
  float world_height = 0.0f;
  /// Share of the image left free around the fitted mesh, per side.
  float margin = 0.05f;
  Eigen::Vector3f background = Eigen::Vector3f(1.0f, 1.0f, 1.0f);
  /// Direction the light comes from (towards the light), in view space (x right, y up, z towards the viewer).
  Eigen::Vector3f light = Eigen::Vector3f(-0.4f, 0.6f, 0.7f);
  /// Share of the colour lit regardless of the light direction.
  float ambient = 0.35f;
};

/// Renders V (#V by 3, metres, Y up) with faces F, each face coloured by the mean of its vertices' colours
/// (#V by 3, RGB in [0, 1]). Throws amt::Error for an invalid mesh (validate_mesh) or a colour count that is
/// not #V.
Image render_mesh(const MatrixX3f& V, const MatrixX3i& F, const MatrixX3f& colors, const RenderOptions& options = {});

/// Colours of a character: body vertices skin-toned, apparel vertices (apparel_mask 1) in a cloth colour.
/// apparel_mask has #V entries (or none: everything body).
MatrixX3f character_colors(int num_vertices, const std::vector<uint8_t>& apparel_mask);

/// render_mesh of `mesh` with character_colors.
Image render_character(const TriMesh& mesh, const std::vector<uint8_t>& apparel_mask,
                       const RenderOptions& options = {});

}  // namespace amt
