#include "data_tools/formats/dataset_file.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <system_error>
#include <unordered_set>
#include <utility>

#include "data_tools/formats/atomic_file.h"
#include "data_tools/formats/hdf5_handle.h"
#include "data_tools/formats/input_file.h"
#include "data_tools/formats/temporary_registry.h"
#include "data_tools/geometry/error.h"

namespace amt {

static_assert(sizeof(Transform34) == 12 * sizeof(float), "Transforms must be arrays of packed 3x4 float blocks");

const char* ground_truth_name(GroundTruth ground_truth) {
  return ground_truth == GroundTruth::kRig ? "rig" : "vertices";
}

namespace {

namespace fs = std::filesystem;

/// Tolerance on the sum of a row of skinning weights.
constexpr float kWeightSumTolerance = 1e-3f;

// === Locations: every message starts with "<file>: <object>"

std::string character_where(const std::string& file, const std::string& name) {
  return file + ": /characters/" + name;
}

std::string clip_where(const std::string& file, const std::string& name) {
  return file + ": /clips/" + name;
}

std::string quoted(const std::string& text) {
  return "\"" + text + "\"";
}

std::string joined(const std::vector<std::string>& names, size_t limit = 8) {
  std::string text;
  for (size_t i = 0; i < names.size() && i < limit; ++i) text += (i > 0 ? ", " : "") + names[i];
  if (names.size() > limit) text += ", ...";
  return text;
}

// A group name under /characters or /clips: HDF5 link names may not contain '/' or be "." .
void check_object_name(const std::string& name, const std::string& where) {
  AMT_CHECK(!name.empty() && name != "." && name.find('/') == std::string::npos, where,
            ": name: expected a non-empty name without '/', found ", quoted(name));
}

void check_split(const std::string& split, const std::string& where) {
  AMT_CHECK(split == "train" || split == "test", where, ": attribute 'split': expected \"train\" or \"test\", found ",
            quoted(split));
}

void check_fps(float fps, const std::string& where) {
  AMT_CHECK(std::isfinite(fps) && fps > 0, where, ": attribute 'fps': expected a positive frame rate, found ", fps);
}

// === Value checks shared by the writer and the reader

// Checks that `count` floats laid out in rows of `row_size` are finite; names the first bad row.
void check_finite(const float* data, size_t count, size_t row_size, const std::string& where, const char* row_noun) {
  for (size_t k = 0; k < count; ++k) {
    if (!std::isfinite(data[k])) {
      fail(where, ": expected finite values, found ", data[k], " at ", row_noun, " ", k / row_size);
    }
  }
}

// Checks that a (N, K) block of skinning weights is non-negative with rows summing to 1.
void check_weight_rows(const MatrixXfR& W, const std::string& where) {
  check_finite(W.data(), static_cast<size_t>(W.size()), static_cast<size_t>(std::max<Eigen::Index>(1, W.cols())), where,
               "vertex");
  for (Eigen::Index i = 0; i < W.rows(); ++i) {
    const float lowest = W.row(i).minCoeff();
    AMT_CHECK(lowest >= 0, where, ": expected non-negative weights, found ", lowest, " at vertex ", i);
    const float sum = W.row(i).sum();
    AMT_CHECK(std::abs(sum - 1.0f) <= kWeightSumTolerance, where, ": expected weights summing to 1, found ", sum,
              " at vertex ", i);
  }
}

void check_transforms(const Transforms& transforms, const std::string& where, const char* noun) {
  check_finite(transforms.empty() ? nullptr : transforms.front().data(), transforms.size() * 12, 12, where, noun);
}

void validate_rig(const Rig& rig, Eigen::Index num_vertices, const std::string& where) {
  const std::string at = where + "/rig";
  const size_t B = rig.bone_names.size();
  AMT_CHECK(B > 0, at, ": attribute 'bone_names': expected at least 1 bone, found none");
  AMT_CHECK(rig.bone_parents.size() == B, at, "/bone_parents: expected B = ", B, " entries (as bone_names), found ",
            rig.bone_parents.size());
  for (size_t b = 0; b < B; ++b) {
    const int32_t p = rig.bone_parents[b];
    AMT_CHECK(p >= -1 && p < static_cast<int32_t>(B) && p != static_cast<int32_t>(b), at,
              "/bone_parents: expected -1 or another bone's index in [0, ", B, "), found ", p, " for bone ", b);
  }
  AMT_CHECK(rig.rest_transforms.size() == B, at, "/rest_transforms: expected B = ", B,
            " transforms (as bone_names), found ", rig.rest_transforms.size());
  check_transforms(rig.rest_transforms, at + "/rest_transforms", "bone");
  const Eigen::Index K = rig.skin_indices.cols();
  AMT_CHECK(rig.skin_indices.rows() == num_vertices, at, "/skin_indices: expected N = ", num_vertices,
            " rows (as rest_vertices), found ", rig.skin_indices.rows());
  AMT_CHECK(K >= 1, at, "/skin_indices: expected K >= 1 influences per vertex, found 0");
  AMT_CHECK(rig.skin_weights.rows() == num_vertices && rig.skin_weights.cols() == K, at,
            "/skin_weights: expected (N,K) = (", num_vertices, ",", K, ") (as skin_indices), found (",
            rig.skin_weights.rows(), ",", rig.skin_weights.cols(), ")");
  for (Eigen::Index i = 0; i < rig.skin_indices.rows(); ++i) {
    for (Eigen::Index k = 0; k < K; ++k) {
      const int32_t b = rig.skin_indices(i, k);
      AMT_CHECK(b >= 0 && b < static_cast<int32_t>(B), at, "/skin_indices: expected bone indices in [0, ", B,
                "), found ", b, " at vertex ", i);
    }
  }
  check_weight_rows(rig.skin_weights, at + "/skin_weights");
  if (rig.response.rows() > 0) {
    AMT_CHECK(rig.response.rows() == static_cast<Eigen::Index>(B) && rig.response.cols() == kRigResponseChannels, at,
              "/response: expected (B,", kRigResponseChannels, ") = (", B, ",", kRigResponseChannels, "), found (",
              rig.response.rows(), ",", rig.response.cols(), ")");
    for (Eigen::Index b = 0; b < rig.response.rows(); ++b) {
      AMT_CHECK(rig.response.row(b).allFinite() && rig.response(b, 0) >= 0 && rig.response(b, 0) <= 1 &&
                    rig.response.row(b).minCoeff() >= 0 && rig.response.row(b).maxCoeff() <= 4,
                at, "/response: expected finite values in [0, 4] with a first column in [0, 1], found ",
                rig.response.row(b), " for bone ", b);
    }
  }
}

// Validates a character against the file's joint names. `where` is "<file>: /characters/<name>".
void validate_character(const CharacterData& c, const std::vector<std::string>& joint_names, const std::string& where) {
  check_split(c.split, where);
  AMT_CHECK(c.skeleton.names == joint_names, where, ": skeleton: expected the file's ", joint_names.size(), " joints (",
            joined(joint_names), "), found ", c.skeleton.names.size(), " (", joined(c.skeleton.names), ")");
  validate_skeleton(c.skeleton, where);
  check_finite(c.mesh.V.data(), static_cast<size_t>(c.mesh.V.size()), 3, where + "/rest_vertices", "vertex");
  validate_mesh(c.mesh, where);
  const Eigen::Index N = c.mesh.V.rows();
  const Eigen::Index J = static_cast<Eigen::Index>(joint_names.size());
  AMT_CHECK(static_cast<Eigen::Index>(c.apparel_mask.size()) == N, where, "/apparel_mask: expected N = ", N,
            " entries (as rest_vertices), found ", c.apparel_mask.size());
  for (size_t i = 0; i < c.apparel_mask.size(); ++i) {
    AMT_CHECK(c.apparel_mask[i] <= 1, where, "/apparel_mask: expected 0 or 1, found ", int(c.apparel_mask[i]),
              " at vertex ", i);
  }
  AMT_CHECK(c.body_weights.rows() == N && c.body_weights.cols() == J, where, "/body_weights: expected (N,J) = (", N,
            ",", J, ") (as rest_vertices and the skeleton), found (", c.body_weights.rows(), ",", c.body_weights.cols(),
            ")");
  check_weight_rows(c.body_weights, where + "/body_weights");
  if (c.rig) validate_rig(*c.rig, N, where);
}

// === Root attributes

/// The root attributes a reader needs.
struct RootInfo {
  int64_t version = 0;
  float fps = 0;
  std::vector<std::string> joint_names;
  /// The optional attribute `predictions` (what made them); empty in a ground-truth file.
  std::string predictions;
};

void write_root(hid_t file, float fps, const std::vector<std::string>& joint_names, const std::string& where) {
  h5::write_string_attribute(file, "format", kDatasetFormat, where);
  h5::write_int_attribute(file, "version", kDatasetVersion, where);
  h5::write_string_attribute(file, "units", "metres", where);
  h5::write_string_attribute(file, "up_axis", "y", where);
  h5::write_float_attribute(file, "fps", fps, where);
  h5::write_string_list_attribute(file, "skeleton", joint_names, where);
}

void check_joint_names(const std::vector<std::string>& names, const std::string& where) {
  AMT_CHECK(!names.empty(), where, ": attribute 'skeleton': expected at least 1 joint name, found none");
  std::unordered_set<std::string> seen;
  for (const std::string& name : names) {
    AMT_CHECK(!name.empty(), where, ": attribute 'skeleton': expected non-empty joint names, found an empty one");
    AMT_CHECK(seen.insert(name).second, where, ": attribute 'skeleton': joint name ", quoted(name), " appears twice");
  }
}

// Reads and checks the root attributes; `path` starts every message.
RootInfo read_root(hid_t file, const std::string& path) {
  AMT_CHECK(h5::has_attribute(file, "format"), path, ": attribute 'format': missing (expected ", quoted(kDatasetFormat),
            "; not an amt dataset file?)");
  const std::string format = h5::read_string_attribute(file, "format", path);
  AMT_CHECK(format == kDatasetFormat, path, ": attribute 'format': expected ", quoted(kDatasetFormat), ", found ",
            quoted(format));
  const int64_t version = h5::read_int_attribute(file, "version", path);
  AMT_CHECK(version >= kDatasetOldestVersion && version <= kDatasetVersion, path, ": attribute 'version': expected ",
            kDatasetOldestVersion, " to ", kDatasetVersion, ", found ", version,
            version > kDatasetVersion ? " (written by a newer amt: update amt to read it)"
                                      : " (not a version any amt wrote)");
  const std::string units = h5::read_string_attribute(file, "units", path);
  AMT_CHECK(units == "metres", path, ": attribute 'units': expected \"metres\", found ", quoted(units));
  const std::string up_axis = h5::read_string_attribute(file, "up_axis", path);
  AMT_CHECK(up_axis == "y", path, ": attribute 'up_axis': expected \"y\", found ", quoted(up_axis));
  RootInfo root;
  root.version = version;
  root.fps = h5::read_float_attribute(file, "fps", path);
  check_fps(root.fps, path);
  root.joint_names = h5::read_string_list_attribute(file, "skeleton", path);
  check_joint_names(root.joint_names, path);
  if (h5::has_attribute(file, kPredictionsAttribute)) {
    root.predictions = h5::read_string_attribute(file, kPredictionsAttribute, path);
    AMT_CHECK(!root.predictions.empty(), path, ": attribute '", kPredictionsAttribute,
              "': expected what made the predictions, found an empty string");
  }
  return root;
}

// === Typed array reads with shape checks

/// Element kinds of the format's arrays.
enum class Elements { kFloat32, kInt32, kUInt8 };

const char* elements_name(Elements elements) {
  switch (elements) {
    case Elements::kFloat32:
      return "float32";
    case Elements::kInt32:
      return "int32";
    default:
      return "uint8";
  }
}

// Opens the array `name` of `group` (its full location `where`) and checks its element class and
// rank, and the fixed dimensions in `dims` (-1 marks a free one). `spec` is the shape in symbols,
// "(N,3)". Returns the dataset; `shape` receives its shape.
h5::Dataset open_array(hid_t group, const std::string& name, const std::string& where, const char* spec,
                       Elements elements, const std::vector<long>& dims, h5::Shape* shape) {
  h5::Dataset dataset = h5::open_dataset(group, name, where, std::string(spec) + " " + elements_name(elements));
  const H5T_class_t type_class = h5::element_class(dataset.get(), where);
  const bool type_ok = elements == Elements::kFloat32 ? type_class == H5T_FLOAT : type_class == H5T_INTEGER;
  AMT_CHECK(type_ok, where, ": expected ", elements_name(elements), " elements, found ",
            h5::element_type_name(dataset.get()));
  *shape = h5::dataset_shape(dataset.get(), where);
  bool shape_ok = shape->size() == dims.size();
  for (size_t d = 0; shape_ok && d < dims.size(); ++d) {
    shape_ok = dims[d] < 0 || (*shape)[d] == static_cast<hsize_t>(dims[d]);
  }
  AMT_CHECK(shape_ok, where, ": expected shape ", spec, ", found ", h5::shape_text(*shape));
  AMT_CHECK(shape->empty() || (*shape)[0] <= static_cast<hsize_t>(1) << 30, where,
            ": expected at most 2^30 rows, found ", (*shape)[0]);
  return dataset;
}

// Checks one dimension against the value another field fixed: "expected N = 500 vertices per frame
// (as /characters/bob/rest_vertices), found 499".
void expect_dim(const std::string& where, const char* symbol, hsize_t expected, hsize_t found, const char* noun,
                const std::string& source) {
  AMT_CHECK(found == expected, where, ": expected ", symbol, " = ", expected, " ", noun, " (as ", source, "), found ",
            found);
}

template <typename T>
hid_t native() {
  return h5::memory_type<T>();
}

// Reads a whole (rows, cols) array into a row-major Eigen matrix.
template <typename Matrix>
Matrix read_matrix(hid_t group, const std::string& name, const std::string& where, const char* spec, Elements elements,
                   long cols) {
  h5::Shape shape;
  const h5::Dataset dataset = open_array(group, name, where, spec, elements, {-1, cols}, &shape);
  Matrix out(static_cast<Eigen::Index>(shape[0]), static_cast<Eigen::Index>(shape[1]));
  h5::read_dataset(dataset.get(), native<typename Matrix::Scalar>(), out.data(), where);
  return out;
}

// Reads a whole 1-D array.
template <typename T>
std::vector<T> read_vector(hid_t group, const std::string& name, const std::string& where, const char* spec,
                           Elements elements) {
  h5::Shape shape;
  const h5::Dataset dataset = open_array(group, name, where, spec, elements, {-1}, &shape);
  std::vector<T> out(static_cast<size_t>(shape[0]));
  h5::read_dataset(dataset.get(), native<T>(), out.data(), where);
  return out;
}

// Reads a whole (B,3,4) array of transforms.
Transforms read_transforms(hid_t group, const std::string& name, const std::string& where, const char* spec) {
  h5::Shape shape;
  const h5::Dataset dataset = open_array(group, name, where, spec, Elements::kFloat32, {-1, 3, 4}, &shape);
  Transforms out(static_cast<size_t>(shape[0]));
  if (!out.empty()) h5::read_dataset(dataset.get(), H5T_NATIVE_FLOAT, out.front().data(), where);
  return out;
}

/// Sizes of a character that its clips are checked against.
struct CharacterShape {
  hsize_t num_vertices = 0;
  /// Bones of the rig; 0 when the character has none.
  hsize_t num_bones = 0;
  bool has_rig = false;
};

// Reads a character's N (and B, when it has a rig) from the dataset shapes only.
CharacterShape read_character_shape(hid_t characters, const std::string& file, const std::string& name) {
  const std::string where = character_where(file, name);
  const h5::Group group = h5::open_group(characters, name, where, "a character group");
  CharacterShape shape;
  h5::Shape dims;
  open_array(group.get(), "rest_vertices", where + "/rest_vertices", "(N,3)", Elements::kFloat32, {-1, 3}, &dims);
  shape.num_vertices = dims[0];
  if (h5::has_child(group.get(), "rig")) {
    const h5::Group rig = h5::open_group(group.get(), "rig", where + "/rig", "a rig group");
    open_array(rig.get(), "rest_transforms", where + "/rig/rest_transforms", "(B,3,4)", Elements::kFloat32, {-1, 3, 4},
               &dims);
    shape.has_rig = true;
    shape.num_bones = dims[0];
  }
  return shape;
}

}  // namespace

// === DatasetWriter

struct DatasetWriter::Impl {
  std::string path;
  std::string temporary;
  float fps = 0;
  std::vector<std::string> joint_names;
  h5::File file;
  h5::Group characters;
  h5::Group clips;
  bool committed = false;
  /// Shapes of the characters written (or found in the file) so far.
  std::map<std::string, CharacterShape> character_shapes;

  // The open clip, if any.
  bool clip_open = false;
  ClipInfo clip;
  hsize_t clip_frame_rows = 0;  // N or B
  int clip_frames = 0;
  h5::Group clip_group;
  h5::Dataset joint_dataset;
  h5::Dataset truth_dataset;

  // The temporary is registered from here on (data_tools/formats/temporary_registry.h): a signal removes it.
  explicit Impl(const std::string& target) : path(target), temporary(amt::temporary_path(target)) {
    register_temporary(temporary);
  }

  // Without a successful commit, the temporary file goes; the target is never touched.
  ~Impl() {
    if (committed) return;
    const h5::QuietErrors quiet;
    close_all();
    discard_temporary(temporary);
  }

  void close_all() {
    truth_dataset.reset();
    joint_dataset.reset();
    clip_group.reset();
    clips.reset();
    characters.reset();
    file.reset();
  }

  void require_writable() const {
    AMT_CHECK(!committed, path, ": the dataset writer was already committed; create a new one to write more");
  }

  const CharacterShape& character_shape(const std::string& name) {
    auto found = character_shapes.find(name);
    if (found == character_shapes.end()) {
      found = character_shapes.emplace(name, read_character_shape(characters.get(), path, name)).first;
    }
    return found->second;
  }

  void require_clip(const char* operation) const {
    require_writable();
    AMT_CHECK(clip_open, path, ": ", operation, ": expected an open clip (call begin_clip first), found none");
  }

  // Checks a frame's joint transforms and ground truth rows, then writes both.
  void append(const Transforms& joint_transforms, const float* truth, hsize_t truth_rows, GroundTruth form) {
    const std::string where = clip_where(path, clip.name);
    AMT_CHECK(form == clip.ground_truth, where, ": append_frame: expected ",
              clip.ground_truth == GroundTruth::kRig ? "rig_transforms" : "vertices",
              " (the clip's ground truth), found ", form == GroundTruth::kRig ? "rig_transforms" : "vertices");
    AMT_CHECK(joint_transforms.size() == joint_names.size(), where,
              "/joint_transforms: expected J = ", joint_names.size(), " transforms per frame (as the skeleton), found ",
              joint_transforms.size(), " at frame ", clip_frames);
    check_transforms(joint_transforms, where + "/joint_transforms", "joint");
    const char* truth_name = form == GroundTruth::kRig ? "rig_transforms" : "vertices";
    const char* symbol = form == GroundTruth::kRig ? "B" : "N";
    const char* noun = form == GroundTruth::kRig ? "bones per frame" : "vertices per frame";
    const std::string source =
        "/characters/" + clip.character + (form == GroundTruth::kRig ? "/rig/rest_transforms" : "/rest_vertices");
    const std::string truth_where = where + "/" + truth_name;
    expect_dim(truth_where, symbol, clip_frame_rows, truth_rows, noun, source);
    const size_t row_size = form == GroundTruth::kRig ? 12 : 3;
    check_finite(truth, truth_rows * row_size, row_size, truth_where, form == GroundTruth::kRig ? "bone" : "vertex");
    h5::append_frames(joint_dataset.get(), H5T_NATIVE_FLOAT, joint_transforms.front().data(), 1,
                      where + "/joint_transforms");
    h5::append_frames(truth_dataset.get(), H5T_NATIVE_FLOAT, truth, 1, truth_where);
    ++clip_frames;
  }
};

DatasetWriter::DatasetWriter(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

DatasetWriter::DatasetWriter(const std::string& path, float fps, const std::vector<std::string>& joint_names) {
  const h5::QuietErrors quiet;
  check_fps(fps, path);
  check_joint_names(joint_names, path);
  create_parent_folder(path);
  check_replaceable_file(path);
  prepare_temporary_file(amt::temporary_path(path));
  impl_ = std::make_unique<Impl>(path);
  impl_->fps = fps;
  impl_->joint_names = joint_names;
  impl_->file = h5::create_file(impl_->temporary, path);
  write_root(impl_->file.get(), fps, joint_names, path);
  impl_->characters = h5::create_group(impl_->file.get(), "characters", path + ": /characters");
  impl_->clips = h5::create_group(impl_->file.get(), "clips", path + ": /clips");
}

DatasetWriter DatasetWriter::append(const std::string& path) {
  const h5::QuietErrors quiet;
  check_input_file(path, "an amt-dataset HDF5 file to append to");
  std::error_code error;
  prepare_temporary_file(amt::temporary_path(path));
  auto impl = std::make_unique<Impl>(path);
  fs::copy_file(path, impl->temporary, fs::copy_options::overwrite_existing, error);
  AMT_CHECK(!error, path, ": cannot copy to the temporary file ", impl->temporary, ": ", error.message());
  impl->file = h5::open_file(impl->temporary, true, path);
  const RootInfo root = read_root(impl->file.get(), path);
  impl->fps = root.fps;
  impl->joint_names = root.joint_names;
  impl->characters = h5::open_group(impl->file.get(), "characters", path + ": /characters", "a group");
  impl->clips = h5::open_group(impl->file.get(), "clips", path + ": /clips", "a group");
  return DatasetWriter(std::move(impl));
}

DatasetWriter::~DatasetWriter() = default;

DatasetWriter::DatasetWriter(DatasetWriter&& other) noexcept = default;
DatasetWriter& DatasetWriter::operator=(DatasetWriter&& other) noexcept = default;

const std::string& DatasetWriter::path() const {
  return impl_->path;
}

void DatasetWriter::mark_predictions(const std::string& made_by) {
  AMT_CHECK(!made_by.empty(), impl_->path, ": attribute '", kPredictionsAttribute,
            "': expected what made the predictions, found an empty string");
  const h5::QuietErrors quiet;
  if (h5::has_attribute(impl_->file.get(), kPredictionsAttribute))
    AMT_CHECK(H5Adelete(impl_->file.get(), kPredictionsAttribute) >= 0, impl_->path, ": attribute '",
              kPredictionsAttribute, "': cannot replace it");
  h5::write_string_attribute(impl_->file.get(), kPredictionsAttribute, made_by, impl_->path);
}
const std::string& DatasetWriter::temporary_path() const {
  return impl_->temporary;
}
float DatasetWriter::fps() const {
  return impl_->fps;
}
const std::vector<std::string>& DatasetWriter::joint_names() const {
  return impl_->joint_names;
}

bool DatasetWriter::has_character(const std::string& name) const {
  const h5::QuietErrors quiet;
  impl_->require_writable();
  return h5::has_child(impl_->characters.get(), name);
}

bool DatasetWriter::has_clip(const std::string& name) const {
  const h5::QuietErrors quiet;
  impl_->require_writable();
  return h5::has_child(impl_->clips.get(), name);
}

void DatasetWriter::add_character(const CharacterData& c) {
  const h5::QuietErrors quiet;
  Impl& w = *impl_;
  w.require_writable();
  const std::string where = character_where(w.path, c.name);
  check_object_name(c.name, where);
  AMT_CHECK(!has_character(c.name), where, ": expected a new character name, found one already in the file");
  validate_character(c, w.joint_names, where);

  const hsize_t N = static_cast<hsize_t>(c.mesh.V.rows()), F = static_cast<hsize_t>(c.mesh.F.rows());
  const hsize_t J = w.joint_names.size();
  const h5::Group group = h5::create_group(w.characters.get(), c.name, where);
  const hid_t g = group.get();
  h5::write_dataset(g, "rest_vertices", c.mesh.V.data(), {N, 3}, true, where + "/rest_vertices");
  h5::write_dataset(g, "faces", c.mesh.F.data(), {F, 3}, true, where + "/faces");
  h5::write_dataset(g, "rest_joints", c.skeleton.rest_joints.data(), {J, 3}, false, where + "/rest_joints");
  h5::write_dataset(g, "joint_parents", c.skeleton.parents.data(), {J}, false, where + "/joint_parents");
  h5::write_dataset(g, "apparel_mask", c.apparel_mask.data(), {N}, true, where + "/apparel_mask");
  h5::write_dataset(g, "body_weights", c.body_weights.data(), {N, J}, true, where + "/body_weights");
  h5::write_string_attribute(g, "split", c.split, where);
  CharacterShape shape;
  shape.num_vertices = N;
  if (c.rig) {
    const Rig& rig = *c.rig;
    const std::string at = where + "/rig";
    const h5::Group rig_group = h5::create_group(g, "rig", at);
    const hid_t r = rig_group.get();
    const hsize_t B = rig.bone_names.size(), K = static_cast<hsize_t>(rig.skin_indices.cols());
    h5::write_string_list_attribute(r, "bone_names", rig.bone_names, at);
    h5::write_dataset(r, "bone_parents", rig.bone_parents.data(), {B}, false, at + "/bone_parents");
    h5::write_dataset(r, "rest_transforms", rig.rest_transforms.front().data(), {B, 3, 4}, false,
                      at + "/rest_transforms");
    h5::write_dataset(r, "skin_indices", rig.skin_indices.data(), {N, K}, true, at + "/skin_indices");
    h5::write_dataset(r, "skin_weights", rig.skin_weights.data(), {N, K}, true, at + "/skin_weights");
    if (rig.response.rows() > 0) {
      h5::write_dataset(r, "response", rig.response.data(), {B, hsize_t(kRigResponseChannels)}, false,
                        at + "/response");
    }
    shape.has_rig = true;
    shape.num_bones = B;
  }
  w.character_shapes[c.name] = shape;
}

void DatasetWriter::begin_clip(const ClipInfo& info) {
  const h5::QuietErrors quiet;
  Impl& w = *impl_;
  w.require_writable();
  const std::string where = clip_where(w.path, info.name);
  AMT_CHECK(!w.clip_open, where, ": begin_clip: expected no open clip, found clip '", w.clip.name,
            "' still open (call end_clip first)");
  check_object_name(info.name, where);
  AMT_CHECK(!has_clip(info.name), where, ": expected a new clip name, found one already in the file");
  AMT_CHECK(has_character(info.character), where, ": attribute 'character': expected a character already in the file, ",
            "found ", quoted(info.character));
  check_split(info.split, where);
  check_fps(info.fps, where);
  const CharacterShape& character = w.character_shape(info.character);
  const bool rig = info.ground_truth == GroundTruth::kRig;
  AMT_CHECK(!rig || character.has_rig, where, ": rig_transforms: expected a rig under /characters/", info.character,
            "/rig for rig ground truth, found none");

  h5::Group group = h5::create_group(w.clips.get(), info.name, where);
  h5::write_string_attribute(group.get(), "character", info.character, where);
  h5::write_string_attribute(group.get(), "motion", info.motion, where);
  h5::write_float_attribute(group.get(), "fps", info.fps, where);
  h5::write_string_attribute(group.get(), "split", info.split, where);
  const hsize_t J = w.joint_names.size();
  w.joint_dataset =
      h5::create_frame_dataset(group.get(), "joint_transforms", H5T_IEEE_F32LE, {J, 3, 4}, where + "/joint_transforms");
  w.clip_frame_rows = rig ? character.num_bones : character.num_vertices;
  const h5::Shape truth_frame = rig ? h5::Shape{w.clip_frame_rows, 3, 4} : h5::Shape{w.clip_frame_rows, 3};
  const std::string truth_name = rig ? "rig_transforms" : "vertices";
  w.truth_dataset =
      h5::create_frame_dataset(group.get(), truth_name, H5T_IEEE_F32LE, truth_frame, where + "/" + truth_name);
  w.clip_group = std::move(group);
  w.clip = info;
  w.clip.num_frames = 0;
  w.clip_frames = 0;
  w.clip_open = true;
}

void DatasetWriter::append_frame(const Transforms& joint_transforms, const MatrixX3f& vertices) {
  const h5::QuietErrors quiet;
  impl_->require_clip("append_frame");
  impl_->append(joint_transforms, vertices.data(), static_cast<hsize_t>(vertices.rows()), GroundTruth::kVertices);
}

void DatasetWriter::append_frame(const Transforms& joint_transforms, const Transforms& rig_transforms) {
  const h5::QuietErrors quiet;
  impl_->require_clip("append_frame");
  impl_->append(joint_transforms, rig_transforms.empty() ? nullptr : rig_transforms.front().data(),
                rig_transforms.size(), GroundTruth::kRig);
}

int DatasetWriter::num_frames_in_clip() const {
  return impl_->clip_open ? impl_->clip_frames : 0;
}

void DatasetWriter::end_clip() {
  const h5::QuietErrors quiet;
  Impl& w = *impl_;
  w.require_clip("end_clip");
  AMT_CHECK(w.clip_frames > 0, clip_where(w.path, w.clip.name),
            ": end_clip: expected at least 1 frame (call append_frame), found 0");
  // The closes flush the clip's last chunks: a failed one (a full disk) is an error, not a silent loss.
  const bool closed = w.truth_dataset.close() >= 0 && w.joint_dataset.close() >= 0;
  w.truth_dataset.reset();
  w.joint_dataset.reset();
  w.clip_group.reset();
  w.clip_open = false;
  if (!closed) h5::fail_hdf5(clip_where(w.path, w.clip.name), "end_clip: cannot write the clip's frames");
}

void DatasetWriter::commit() {
  const h5::QuietErrors quiet;
  Impl& w = *impl_;
  w.require_writable();
  AMT_CHECK(!w.clip_open, w.path, ": commit: expected every clip ended, found clip '", w.clip.name,
            "' still open (call end_clip first)");
  w.clips.reset();
  w.characters.reset();
  if (w.file.close() < 0) h5::fail_hdf5(w.path, "cannot close the temporary file " + w.temporary);
  replace_with_temporary(w.temporary, w.path);
  w.committed = true;
}

// === DatasetReader

namespace {

/// A checked clip and its character's per-frame row count (N or B).
struct ClipMeta {
  ClipInfo info;
  hsize_t frame_rows = 0;
};

/// What skinning a rig clip needs from its character.
struct SkinData {
  MatrixX3f rest_vertices;
  MatrixXiR skin_indices;
  MatrixXfR skin_weights;
};

}  // namespace

struct DatasetReader::Impl {
  std::string path;
  h5::File file;
  h5::Group characters;
  h5::Group clips;
  RootInfo root;
  std::vector<std::string> character_names;
  std::vector<std::string> clip_names;
  mutable std::map<std::string, ClipMeta> clip_cache;
  mutable std::map<std::string, SkinData> skin_cache;

  ~Impl() {
    const h5::QuietErrors quiet;
    clips.reset();
    characters.reset();
    file.reset();
  }

  const ClipMeta& clip(const std::string& name) const;
  const SkinData& skin(const std::string& character) const;
  CharacterData read_character(const std::string& name) const;
  // Checks that [first, first + count) lies in the clip.
  void check_range(const ClipMeta& meta, int first, int count) const {
    AMT_CHECK(first >= 0 && count >= 0 && first <= meta.info.num_frames - count, clip_where(path, meta.info.name),
              ": frames [", first, ", ", static_cast<int64_t>(first) + count, "): expected a range within [0, ",
              meta.info.num_frames, ")");
  }
};

CharacterData DatasetReader::Impl::read_character(const std::string& name) const {
  const std::string where = character_where(path, name);
  const h5::Group group = h5::open_group(characters.get(), name, where, "a character group");
  const hid_t g = group.get();
  CharacterData c;
  c.name = name;
  c.mesh.V = read_matrix<MatrixX3f>(g, "rest_vertices", where + "/rest_vertices", "(N,3)", Elements::kFloat32, 3);
  c.mesh.F = read_matrix<MatrixX3i>(g, "faces", where + "/faces", "(F,3)", Elements::kInt32, 3);
  c.skeleton.names = root.joint_names;
  c.skeleton.rest_joints =
      read_matrix<MatrixX3f>(g, "rest_joints", where + "/rest_joints", "(J,3)", Elements::kFloat32, 3);
  c.skeleton.parents = read_vector<int32_t>(g, "joint_parents", where + "/joint_parents", "(J)", Elements::kInt32);
  c.apparel_mask = read_vector<uint8_t>(g, "apparel_mask", where + "/apparel_mask", "(N)", Elements::kUInt8);
  c.body_weights = read_matrix<MatrixXfR>(g, "body_weights", where + "/body_weights", "(N,J)", Elements::kFloat32, -1);
  c.split = h5::read_string_attribute(g, "split", where);
  if (h5::has_child(g, "rig")) {
    const std::string at = where + "/rig";
    const h5::Group rig_group = h5::open_group(g, "rig", at, "a rig group");
    const hid_t r = rig_group.get();
    Rig rig;
    rig.bone_names = h5::read_string_list_attribute(r, "bone_names", at);
    rig.bone_parents = read_vector<int32_t>(r, "bone_parents", at + "/bone_parents", "(B)", Elements::kInt32);
    rig.rest_transforms = read_transforms(r, "rest_transforms", at + "/rest_transforms", "(B,3,4)");
    rig.skin_indices = read_matrix<MatrixXiR>(r, "skin_indices", at + "/skin_indices", "(N,K)", Elements::kInt32, -1);
    rig.skin_weights = read_matrix<MatrixXfR>(r, "skin_weights", at + "/skin_weights", "(N,K)", Elements::kFloat32, -1);
    if (h5::has_child(r, "response")) {
      rig.response =
          read_matrix<MatrixXfR>(r, "response", at + "/response", "(B,3)", Elements::kFloat32, kRigResponseChannels);
    }
    c.rig = std::move(rig);
  }
  validate_character(c, root.joint_names, where);
  return c;
}

const ClipMeta& DatasetReader::Impl::clip(const std::string& name) const {
  const auto cached = clip_cache.find(name);
  if (cached != clip_cache.end()) return cached->second;

  const std::string where = clip_where(path, name);
  const h5::Group group = h5::open_group(clips.get(), name, where, "a clip group");
  const hid_t g = group.get();
  ClipMeta meta;
  ClipInfo& info = meta.info;
  info.name = name;
  info.character = h5::read_string_attribute(g, "character", where);
  info.motion = h5::read_string_attribute(g, "motion", where);
  info.split = h5::read_string_attribute(g, "split", where);
  check_split(info.split, where);
  info.fps = h5::read_float_attribute(g, "fps", where);
  check_fps(info.fps, where);
  AMT_CHECK(h5::has_child(characters.get(), info.character), where,
            ": attribute 'character': expected a character under /characters, found ", quoted(info.character));
  const CharacterShape character = read_character_shape(characters.get(), path, info.character);

  h5::Shape joints;
  open_array(g, "joint_transforms", where + "/joint_transforms", "(T,J,3,4)", Elements::kFloat32, {-1, -1, 3, 4},
             &joints);
  expect_dim(where + "/joint_transforms", "J", root.joint_names.size(), joints[1], "joints per frame",
             "the root attribute 'skeleton'");
  AMT_CHECK(joints[0] >= 1, where, "/joint_transforms: expected at least 1 frame, found 0");

  const bool has_vertices = h5::has_child(g, "vertices"), has_rig = h5::has_child(g, "rig_transforms");
  AMT_CHECK(!(has_vertices && has_rig), where,
            ": ground truth: expected either vertices or rig_transforms, found both");
  AMT_CHECK(has_vertices || has_rig, where,
            "/vertices: missing (expected dataset vertices (T,N,3) float32, or rig_transforms (T,B,3,4) float32)");
  h5::Shape truth;
  std::string truth_where;
  if (has_vertices) {
    info.ground_truth = GroundTruth::kVertices;
    truth_where = where + "/vertices";
    open_array(g, "vertices", truth_where, "(T,N,3)", Elements::kFloat32, {-1, -1, 3}, &truth);
    expect_dim(truth_where, "N", character.num_vertices, truth[1], "vertices per frame",
               "/characters/" + info.character + "/rest_vertices");
  } else {
    info.ground_truth = GroundTruth::kRig;
    truth_where = where + "/rig_transforms";
    AMT_CHECK(character.has_rig, truth_where, ": expected a rig under /characters/", info.character,
              "/rig, found none");
    open_array(g, "rig_transforms", truth_where, "(T,B,3,4)", Elements::kFloat32, {-1, -1, 3, 4}, &truth);
    expect_dim(truth_where, "B", character.num_bones, truth[1], "bones per frame",
               "/characters/" + info.character + "/rig/rest_transforms");
  }
  expect_dim(truth_where, "T", joints[0], truth[0], "frames", "joint_transforms");
  info.num_frames = static_cast<int>(joints[0]);
  meta.frame_rows = truth[1];
  return clip_cache.emplace(name, std::move(meta)).first->second;
}

const SkinData& DatasetReader::Impl::skin(const std::string& character) const {
  const auto cached = skin_cache.find(character);
  if (cached != skin_cache.end()) return cached->second;
  CharacterData c = read_character(character);
  SkinData data;
  data.rest_vertices = std::move(c.mesh.V);
  data.skin_indices = std::move(c.rig->skin_indices);
  data.skin_weights = std::move(c.rig->skin_weights);
  return skin_cache.emplace(character, std::move(data)).first->second;
}

DatasetReader::DatasetReader(const std::string& path) : impl_(std::make_unique<Impl>()) {
  const h5::QuietErrors quiet;
  Impl& r = *impl_;
  r.path = path;
  check_input_file(path, "an amt-dataset HDF5 file");
  AMT_CHECK(h5::is_hdf5_file(path), path, ": expected an HDF5 file (format ", quoted(kDatasetFormat),
            "), found a file that is not HDF5");
  r.file = h5::open_file(path, false, path);
  r.root = read_root(r.file.get(), path);
  r.characters = h5::open_group(r.file.get(), "characters", path + ": /characters", "a group of characters");
  r.clips = h5::open_group(r.file.get(), "clips", path + ": /clips", "a group of clips");
  r.character_names = h5::child_names(r.characters.get(), path + ": /characters");
  r.clip_names = h5::child_names(r.clips.get(), path + ": /clips");
}

DatasetReader::~DatasetReader() = default;

DatasetReader::DatasetReader(DatasetReader&& other) noexcept = default;
DatasetReader& DatasetReader::operator=(DatasetReader&& other) noexcept = default;

const std::string& DatasetReader::path() const {
  return impl_->path;
}
float DatasetReader::fps() const {
  return impl_->root.fps;
}
int DatasetReader::version() const {
  return int(impl_->root.version);
}
const std::string& DatasetReader::predictions() const {
  return impl_->root.predictions;
}
int64_t DatasetReader::verify() const {
  return h5::verify_datasets(impl_->file.get(), impl_->path);
}
const std::vector<std::string>& DatasetReader::joint_names() const {
  return impl_->root.joint_names;
}
int DatasetReader::num_joints() const {
  return static_cast<int>(impl_->root.joint_names.size());
}
const std::vector<std::string>& DatasetReader::character_names() const {
  return impl_->character_names;
}
const std::vector<std::string>& DatasetReader::clip_names() const {
  return impl_->clip_names;
}

bool DatasetReader::has_character(const std::string& name) const {
  return std::binary_search(impl_->character_names.begin(), impl_->character_names.end(), name);
}

bool DatasetReader::has_clip(const std::string& name) const {
  return std::binary_search(impl_->clip_names.begin(), impl_->clip_names.end(), name);
}

CharacterData DatasetReader::read_character(const std::string& name) const {
  const h5::QuietErrors quiet;
  return impl_->read_character(name);
}

CharacterSummary DatasetReader::character_summary(const std::string& name) const {
  const h5::QuietErrors quiet;
  const Impl& r = *impl_;
  const std::string where = character_where(r.path, name);
  const h5::Group group = h5::open_group(r.characters.get(), name, where, "a character group");
  const hid_t g = group.get();
  CharacterSummary summary;
  summary.name = name;
  h5::Shape shape;
  open_array(g, "rest_vertices", where + "/rest_vertices", "(N,3)", Elements::kFloat32, {-1, 3}, &shape);
  const hsize_t N = shape[0];
  AMT_CHECK(N > 0, where, "/rest_vertices: expected at least 1 vertex, found an empty mesh");
  open_array(g, "faces", where + "/faces", "(F,3)", Elements::kInt32, {-1, 3}, &shape);
  AMT_CHECK(shape[0] > 0, where, "/faces: expected at least 1 triangle, found none");
  summary.num_vertices = static_cast<int>(N);
  summary.num_faces = static_cast<int>(shape[0]);
  const std::vector<uint8_t> mask =
      read_vector<uint8_t>(g, "apparel_mask", where + "/apparel_mask", "(N)", Elements::kUInt8);
  expect_dim(where + "/apparel_mask", "N", N, mask.size(), "entries", "rest_vertices");
  for (size_t i = 0; i < mask.size(); ++i) {
    AMT_CHECK(mask[i] <= 1, where, "/apparel_mask: expected 0 or 1, found ", int(mask[i]), " at vertex ", i);
    summary.num_apparel_vertices += mask[i];
  }
  open_array(g, "body_weights", where + "/body_weights", "(N,J)", Elements::kFloat32, {-1, -1}, &shape);
  expect_dim(where + "/body_weights", "N", N, shape[0], "rows", "rest_vertices");
  expect_dim(where + "/body_weights", "J", r.root.joint_names.size(), shape[1], "columns",
             "the root attribute 'skeleton'");
  summary.split = h5::read_string_attribute(g, "split", where);
  check_split(summary.split, where);
  const CharacterShape character = read_character_shape(r.characters.get(), r.path, name);
  summary.num_bones = static_cast<int>(character.num_bones);
  return summary;
}

ClipInfo DatasetReader::clip_info(const std::string& clip) const {
  const h5::QuietErrors quiet;
  return impl_->clip(clip).info;
}

Transforms DatasetReader::read_joint_transforms(const std::string& clip, int first_frame, int count) const {
  const h5::QuietErrors quiet;
  const Impl& r = *impl_;
  const ClipMeta& meta = r.clip(clip);
  r.check_range(meta, first_frame, count);
  const std::string where = clip_where(r.path, clip) + "/joint_transforms";
  const size_t J = r.root.joint_names.size();
  Transforms out(static_cast<size_t>(count) * J);
  if (count == 0) return out;
  const h5::Group group = h5::open_group(r.clips.get(), clip, clip_where(r.path, clip), "a clip group");
  const h5::Dataset dataset = h5::open_dataset(group.get(), "joint_transforms", where, "(T,J,3,4) float32");
  h5::read_frames(dataset.get(), static_cast<hsize_t>(first_frame), static_cast<hsize_t>(count), H5T_NATIVE_FLOAT,
                  out.front().data(), where);
  for (size_t k = 0; k < out.size(); ++k) {
    AMT_CHECK(out[k].allFinite(), where, ": expected finite values, found a NaN or infinity at frame ",
              first_frame + static_cast<int>(k / J), ", joint ", k % J, " (", r.root.joint_names[k % J], ")");
  }
  return out;
}

Transforms DatasetReader::read_rig_transforms(const std::string& clip, int first_frame, int count) const {
  const h5::QuietErrors quiet;
  const Impl& r = *impl_;
  const ClipMeta& meta = r.clip(clip);
  const std::string where = clip_where(r.path, clip) + "/rig_transforms";
  AMT_CHECK(meta.info.ground_truth == GroundTruth::kRig, where,
            ": expected a clip with rig ground truth, found one that stores vertices");
  r.check_range(meta, first_frame, count);
  const size_t B = meta.frame_rows;
  Transforms out(static_cast<size_t>(count) * B);
  if (out.empty()) return out;
  const h5::Group group = h5::open_group(r.clips.get(), clip, clip_where(r.path, clip), "a clip group");
  const h5::Dataset dataset = h5::open_dataset(group.get(), "rig_transforms", where, "(T,B,3,4) float32");
  h5::read_frames(dataset.get(), static_cast<hsize_t>(first_frame), static_cast<hsize_t>(count), H5T_NATIVE_FLOAT,
                  out.front().data(), where);
  for (size_t k = 0; k < out.size(); ++k) {
    AMT_CHECK(out[k].allFinite(), where, ": expected finite values, found a NaN or infinity at frame ",
              first_frame + static_cast<int>(k / B), ", bone ", k % B);
  }
  return out;
}

MatrixX3f DatasetReader::read_vertices(const std::string& clip, int first_frame, int count) const {
  const h5::QuietErrors quiet;
  const Impl& r = *impl_;
  const ClipMeta& meta = r.clip(clip);
  r.check_range(meta, first_frame, count);
  const Eigen::Index N = static_cast<Eigen::Index>(meta.frame_rows);
  if (meta.info.ground_truth == GroundTruth::kRig) {
    const SkinData& skin = r.skin(meta.info.character);
    const Transforms M = read_rig_transforms(clip, first_frame, count);
    const size_t B = meta.frame_rows;
    const Eigen::Index K = skin.skin_indices.cols();
    MatrixX3f out(static_cast<Eigen::Index>(count) * skin.rest_vertices.rows(), 3);
    for (int t = 0; t < count; ++t) {
      const Transform34* frame = M.data() + static_cast<size_t>(t) * B;
      const Eigen::Index offset = static_cast<Eigen::Index>(t) * skin.rest_vertices.rows();
      // v = sum_k w_k M_{b_k} [v_rest; 1]: blend the matrices, then apply once.
#pragma omp parallel for schedule(static)
      for (Eigen::Index i = 0; i < skin.rest_vertices.rows(); ++i) {
        Transform34 blend = Transform34::Zero();
        for (Eigen::Index k = 0; k < K; ++k) {
          const float w = skin.skin_weights(i, k);
          if (w != 0.0f) blend += w * frame[skin.skin_indices(i, k)];
        }
        out.row(offset + i) = (blend.leftCols<3>() * skin.rest_vertices.row(i).transpose() + blend.col(3)).transpose();
      }
    }
    return out;
  }
  const std::string where = clip_where(r.path, clip) + "/vertices";
  MatrixX3f out(static_cast<Eigen::Index>(count) * N, 3);
  if (out.size() == 0) return out;
  const h5::Group group = h5::open_group(r.clips.get(), clip, clip_where(r.path, clip), "a clip group");
  const h5::Dataset dataset = h5::open_dataset(group.get(), "vertices", where, "(T,N,3) float32");
  h5::read_frames(dataset.get(), static_cast<hsize_t>(first_frame), static_cast<hsize_t>(count), H5T_NATIVE_FLOAT,
                  out.data(), where);
  for (Eigen::Index row = 0; row < out.rows(); ++row) {
    AMT_CHECK(out.row(row).allFinite(), where, ": expected finite values, found a NaN or infinity at frame ",
              first_frame + row / N, ", vertex ", row % N);
  }
  return out;
}

std::optional<ApparelBones> rig_apparel_bones(const CharacterData& character) {
  if (!character.rig) return std::nullopt;
  const Rig& rig = *character.rig;
  const std::unordered_set<std::string> joints(character.skeleton.names.begin(), character.skeleton.names.end());
  const int B = rig.num_bones();
  std::vector<uint8_t> keep(static_cast<size_t>(B), 0);
  MatrixX3f heads(B, 3);
  for (int b = 0; b < B; ++b) {
    keep[b] = joints.count(rig.bone_names[b]) == 0;
    heads.row(b) = rig.rest_transforms[b].col(3).transpose();
  }
  if (std::find(keep.begin(), keep.end(), uint8_t(1)) == keep.end()) return std::nullopt;
  return select_apparel_bones(rig.bone_names, heads, rig.bone_parents, rig.skin_indices, rig.skin_weights, keep,
                              rig.response);
}

}  // namespace amt
