#include "data_tools/formats/hdf5_handle.h"

#include <algorithm>
#include <numeric>

#include "data_tools/geometry/error.h"

namespace amt::h5 {

// === Errors

namespace {

// HDF5 closes the files still open when the process exits, from an atexit handler. A file whose
// close failed (a full disk: its flush fails) is left half closed, and that handler then crashed in
// H5F__close_cb (exit 139 after the one-line error). amt closes every id itself (the handles above),
// so the handler is turned off before the library is first used: this runs when the program loads.
[[maybe_unused]] const bool kNoExitHandler = [] {
  H5dont_atexit();
  return true;
}();

// HDF5's innermost message can span lines ("file write failed: time = ...\n, filename = '...', ...,
// error message = 'File too large', ..."): its first clause and the system's message, on one line.
std::string one_line(const std::string& message) {
  const std::string marker = "error message = '";
  const size_t at = message.find(marker);
  if (at != std::string::npos) {
    const size_t from = at + marker.size(), to = message.find('\'', from);
    return message.substr(0, message.find(':')) + " (" + message.substr(from, to - from) + ")";
  }
  std::string line = message;
  std::replace_if(line.begin(), line.end(), [](char c) { return c == '\n' || c == '\r'; }, ' ');
  return line;
}

}  // namespace

QuietErrors::QuietErrors() {
  H5Eget_auto2(H5E_DEFAULT, &previous_function_, &previous_data_);
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
}

QuietErrors::~QuietErrors() {
  H5Eset_auto2(H5E_DEFAULT, previous_function_, previous_data_);
}

namespace {

herr_t take_innermost(unsigned n, const H5E_error2_t* error, void* client_data) {
  if (n == 0 && error->desc != nullptr) *static_cast<std::string*>(client_data) = error->desc;
  return 0;
}

}  // namespace

std::string last_error_message() {
  std::string message;
  H5Ewalk2(H5E_DEFAULT, H5E_WALK_UPWARD, &take_innermost, &message);
  return message;
}

void fail_hdf5(const std::string& where, const std::string& what) {
  const std::string detail = one_line(last_error_message());
  H5Eclear2(H5E_DEFAULT);
  if (detail.empty()) fail(where, ": ", what);
  fail(where, ": ", what, ": ", detail);
}

// === Files and groups

namespace {

PropertyList strong_close_access() {
  PropertyList access(H5Pcreate(H5P_FILE_ACCESS));
  if (!access || H5Pset_fclose_degree(access.get(), H5F_CLOSE_STRONG) < 0) {
    fail_hdf5("HDF5", "cannot create a file access property list");
  }
  return access;
}

}  // namespace

bool is_hdf5_file(const std::string& path) {
#if H5_VERSION_GE(1, 12, 0)
  return H5Fis_accessible(path.c_str(), H5P_DEFAULT) > 0;
#else
  return H5Fis_hdf5(path.c_str()) > 0;
#endif
}

File create_file(const std::string& path, const std::string& where) {
  const PropertyList access = strong_close_access();
  // The 1.8 file format and later checksum their metadata (object headers, B-trees, heaps): a
  // damaged header is an error on open rather than garbage.
  if (H5Pset_libver_bounds(access.get(), H5F_LIBVER_V18, H5F_LIBVER_LATEST) < 0) {
    fail_hdf5(where, "cannot select the HDF5 file format");
  }
  // No modification times in the root group's header either (the 1.8 format stores them).
  const PropertyList creation(H5Pcreate(H5P_FILE_CREATE));
  if (!creation || H5Pset_obj_track_times(creation.get(), 0) < 0) fail_hdf5(where, "cannot create the file");
  File file(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, creation.get(), access.get()));
  if (!file) fail_hdf5(where, "cannot create the HDF5 file " + path);
  return file;
}

File open_file(const std::string& path, bool writable, const std::string& where) {
  const PropertyList access = strong_close_access();
  File file(H5Fopen(path.c_str(), writable ? H5F_ACC_RDWR : H5F_ACC_RDONLY, access.get()));
  if (!file) fail_hdf5(where, "cannot open as HDF5 (damaged or truncated file?)");
  return file;
}

bool has_child(hid_t loc, const std::string& name) {
  if (name.empty() || name.find('/') != std::string::npos) return false;
  return H5Lexists(loc, name.c_str(), H5P_DEFAULT) > 0;
}

Group create_group(hid_t loc, const std::string& name, const std::string& where) {
  // No modification times in object headers: the same content gives the same bytes (reproducible shards).
  const PropertyList creation(H5Pcreate(H5P_GROUP_CREATE));
  if (!creation || H5Pset_obj_track_times(creation.get(), 0) < 0) fail_hdf5(where, "cannot create the group");
  Group group(H5Gcreate2(loc, name.c_str(), H5P_DEFAULT, creation.get(), H5P_DEFAULT));
  if (!group) fail_hdf5(where, "cannot create the group");
  return group;
}

Group open_group(hid_t loc, const std::string& name, const std::string& where, const std::string& expected) {
  if (!has_child(loc, name)) fail(where, ": missing (expected ", expected, ")");
  Group group(H5Gopen2(loc, name.c_str(), H5P_DEFAULT));
  if (!group) fail_hdf5(where, "expected " + expected + ", found something that is not a group");
  return group;
}

namespace {

herr_t collect_name(hid_t, const char* name, const H5L_info_t*, void* client_data) {
  static_cast<std::vector<std::string>*>(client_data)->emplace_back(name);
  return 0;
}

}  // namespace

std::vector<std::string> child_names(hid_t group, const std::string& where) {
  std::vector<std::string> names;
  hsize_t index = 0;
  if (H5Literate(group, H5_INDEX_NAME, H5_ITER_INC, &index, &collect_name, &names) < 0) {
    fail_hdf5(where, "cannot list the group's members");
  }
  std::sort(names.begin(), names.end());
  return names;
}

// === Attributes

namespace {

Datatype variable_string_type(H5T_cset_t cset) {
  Datatype type(H5Tcopy(H5T_C_S1));
  if (!type || H5Tset_size(type.get(), H5T_VARIABLE) < 0 || H5Tset_cset(type.get(), cset) < 0) {
    fail_hdf5("HDF5", "cannot create a string type");
  }
  return type;
}

std::string attribute_where(const std::string& where, const std::string& name) {
  return where + ": attribute '" + name + "'";
}

void write_attribute(hid_t obj, const std::string& name, hid_t file_type, hid_t memory_type, hid_t space,
                     const void* data, const std::string& where) {
  const std::string at = attribute_where(where, name);
  if (has_attribute(obj, name) && H5Adelete(obj, name.c_str()) < 0) fail_hdf5(at, "cannot replace the attribute");
  Attribute attribute(H5Acreate2(obj, name.c_str(), file_type, space, H5P_DEFAULT, H5P_DEFAULT));
  if (!attribute) fail_hdf5(at, "cannot create the attribute");
  if (H5Awrite(attribute.get(), memory_type, data) < 0) fail_hdf5(at, "cannot write the attribute");
}

Attribute open_attribute(hid_t obj, const std::string& name, const std::string& at, const std::string& expected) {
  if (!has_attribute(obj, name)) fail(at, ": missing (expected ", expected, ")");
  Attribute attribute(H5Aopen(obj, name.c_str(), H5P_DEFAULT));
  if (!attribute) fail_hdf5(at, "cannot open the attribute");
  return attribute;
}

const char* class_description(H5T_class_t type_class) {
  switch (type_class) {
    case H5T_INTEGER:
      return "an integer";
    case H5T_FLOAT:
      return "a float";
    case H5T_STRING:
      return "a string";
    case H5T_ENUM:
      return "an enum";
    case H5T_COMPOUND:
      return "a compound value";
    case H5T_ARRAY:
      return "an array type";
    case H5T_VLEN:
      return "a variable-length sequence";
    default:
      return "a value of another type";
  }
}

// Reads every string of a string attribute, whatever its dataspace (scalar or 1-D).
std::vector<std::string> read_strings(hid_t attribute, const std::string& at, const std::string& expected) {
  const Datatype stored(H5Aget_type(attribute));
  const Dataspace space(H5Aget_space(attribute));
  if (!stored || !space) fail_hdf5(at, "cannot read the attribute's type");
  const H5T_class_t type_class = H5Tget_class(stored.get());
  if (type_class != H5T_STRING) fail(at, ": expected ", expected, ", found ", class_description(type_class));
  const hssize_t count = H5Sget_simple_extent_npoints(space.get());
  if (count < 0) fail_hdf5(at, "cannot read the attribute's shape");
  std::vector<std::string> values;
  values.reserve(static_cast<size_t>(count));
  if (count == 0) return values;
  if (H5Tis_variable_str(stored.get()) > 0) {
    const Datatype memory = variable_string_type(H5Tget_cset(stored.get()));
    std::vector<char*> buffer(static_cast<size_t>(count), nullptr);
    if (H5Aread(attribute, memory.get(), buffer.data()) < 0) fail_hdf5(at, "cannot read the attribute");
    for (char* text : buffer) {
      values.emplace_back(text != nullptr ? text : "");
      H5free_memory(text);
    }
  } else {
    const size_t size = H5Tget_size(stored.get());
    const Datatype memory(H5Tcopy(stored.get()));
    std::vector<char> buffer(size * static_cast<size_t>(count) + 1, '\0');
    if (!memory || H5Aread(attribute, memory.get(), buffer.data()) < 0) fail_hdf5(at, "cannot read the attribute");
    for (hssize_t i = 0; i < count; ++i) {
      const char* begin = buffer.data() + static_cast<size_t>(i) * size;
      values.emplace_back(begin, std::find(begin, begin + size, '\0'));
    }
  }
  return values;
}

// Reads a one-element numeric attribute of an accepted type class into `out` as `memory_type`.
void read_number(hid_t obj, const std::string& name, const std::string& where, bool accept_float, hid_t memory_type,
                 void* out) {
  const std::string at = attribute_where(where, name);
  const char* expected = accept_float ? "a number" : "an integer";
  const Attribute attribute = open_attribute(obj, name, at, expected);
  const Datatype stored(H5Aget_type(attribute.get()));
  const Dataspace space(H5Aget_space(attribute.get()));
  if (!stored || !space) fail_hdf5(at, "cannot read the attribute's type");
  const H5T_class_t type_class = H5Tget_class(stored.get());
  if (type_class != H5T_INTEGER && !(accept_float && type_class == H5T_FLOAT)) {
    fail(at, ": expected ", expected, ", found ", class_description(type_class));
  }
  const hssize_t count = H5Sget_simple_extent_npoints(space.get());
  if (count != 1) fail(at, ": expected a single value, found ", count, " values");
  if (H5Aread(attribute.get(), memory_type, out) < 0) fail_hdf5(at, "cannot read the attribute");
}

}  // namespace

bool has_attribute(hid_t obj, const std::string& name) {
  return H5Aexists(obj, name.c_str()) > 0;
}

void write_string_attribute(hid_t obj, const std::string& name, const std::string& value, const std::string& where) {
  const Datatype type = variable_string_type(H5T_CSET_UTF8);
  const Dataspace space(H5Screate(H5S_SCALAR));
  const char* text = value.c_str();
  write_attribute(obj, name, type.get(), type.get(), space.get(), &text, where);
}

void write_string_list_attribute(hid_t obj, const std::string& name, const std::vector<std::string>& values,
                                 const std::string& where) {
  const Datatype type = variable_string_type(H5T_CSET_UTF8);
  const hsize_t count = values.size();
  const Dataspace space(count > 0 ? H5Screate_simple(1, &count, nullptr) : H5Screate(H5S_NULL));
  std::vector<const char*> texts;
  texts.reserve(values.size());
  for (const std::string& value : values) texts.push_back(value.c_str());
  write_attribute(obj, name, type.get(), type.get(), space.get(), texts.data(), where);
}

void write_float_attribute(hid_t obj, const std::string& name, float value, const std::string& where) {
  const Dataspace space(H5Screate(H5S_SCALAR));
  write_attribute(obj, name, H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, space.get(), &value, where);
}

void write_int_attribute(hid_t obj, const std::string& name, int32_t value, const std::string& where) {
  const Dataspace space(H5Screate(H5S_SCALAR));
  write_attribute(obj, name, H5T_STD_I32LE, H5T_NATIVE_INT32, space.get(), &value, where);
}

std::string read_string_attribute(hid_t obj, const std::string& name, const std::string& where) {
  const std::string at = attribute_where(where, name);
  const Attribute attribute = open_attribute(obj, name, at, "a string");
  std::vector<std::string> values = read_strings(attribute.get(), at, "a string");
  if (values.size() != 1) fail(at, ": expected a single string, found ", values.size(), " strings");
  return std::move(values.front());
}

std::vector<std::string> read_string_list_attribute(hid_t obj, const std::string& name, const std::string& where) {
  const std::string at = attribute_where(where, name);
  const Attribute attribute = open_attribute(obj, name, at, "a list of strings");
  return read_strings(attribute.get(), at, "a list of strings");
}

float read_float_attribute(hid_t obj, const std::string& name, const std::string& where) {
  float value = 0;
  read_number(obj, name, where, true, H5T_NATIVE_FLOAT, &value);
  return value;
}

int64_t read_int_attribute(hid_t obj, const std::string& name, const std::string& where) {
  int64_t value = 0;
  read_number(obj, name, where, false, H5T_NATIVE_INT64, &value);
  return value;
}

// === Datasets

std::string shape_text(const Shape& shape) {
  std::string text = "(";
  for (size_t d = 0; d < shape.size(); ++d) {
    if (d > 0) text += ",";
    text += std::to_string(shape[d]);
  }
  return text + ")";
}

Dataset open_dataset(hid_t loc, const std::string& name, const std::string& where, const std::string& expected) {
  if (!has_child(loc, name)) fail(where, ": missing (expected dataset ", expected, ")");
  {
    // Opening the object first tells a group from a dataset without the versioned H5Oget_info API.
    const Object object(H5Oopen(loc, name.c_str(), H5P_DEFAULT));
    if (!object) fail_hdf5(where, "cannot open");
    const H5I_type_t kind = H5Iget_type(object.get());
    if (kind != H5I_DATASET) {
      fail(where, ": expected dataset ", expected, ", found ", kind == H5I_GROUP ? "a group" : "another object");
    }
  }
  Dataset dataset(H5Dopen2(loc, name.c_str(), H5P_DEFAULT));
  if (!dataset) fail_hdf5(where, "cannot open the dataset");
  return dataset;
}

Shape dataset_shape(hid_t dataset, const std::string& where) {
  const Dataspace space(H5Dget_space(dataset));
  if (!space) fail_hdf5(where, "cannot read the dataset's shape");
  const int rank = H5Sget_simple_extent_ndims(space.get());
  if (rank < 0) fail_hdf5(where, "cannot read the dataset's shape");
  Shape shape(static_cast<size_t>(rank));
  if (rank > 0 && H5Sget_simple_extent_dims(space.get(), shape.data(), nullptr) < 0) {
    fail_hdf5(where, "cannot read the dataset's shape");
  }
  return shape;
}

H5T_class_t element_class(hid_t dataset, const std::string& where) {
  const Datatype type(H5Dget_type(dataset));
  if (!type) fail_hdf5(where, "cannot read the dataset's element type");
  return H5Tget_class(type.get());
}

std::string element_type_name(hid_t dataset) {
  const Datatype type(H5Dget_type(dataset));
  if (!type) return "unknown";
  const size_t bits = H5Tget_size(type.get()) * 8;
  switch (H5Tget_class(type.get())) {
    case H5T_FLOAT:
      return "float" + std::to_string(bits);
    case H5T_INTEGER:
      return (H5Tget_sign(type.get()) == H5T_SGN_NONE ? "uint" : "int") + std::to_string(bits);
    case H5T_STRING:
      return "string";
    case H5T_ENUM:
      return "enum";
    case H5T_COMPOUND:
      return "compound";
    default:
      return "another type";
  }
}

namespace {

hsize_t element_count(const Shape& shape) {
  return std::accumulate(shape.begin(), shape.end(), hsize_t{1}, std::multiplies<hsize_t>());
}

// Chunked storage with HDF5's Fletcher-32 checksum of every chunk as stored (after compression when
// `compress`), which every read verifies: a flipped byte in the payload is an error, not a value.
void set_chunks(hid_t creation, const Shape& chunk, bool compress, const std::string& where) {
  if (H5Pset_chunk(creation, static_cast<int>(chunk.size()), chunk.data()) < 0 ||
      (compress && (H5Pset_shuffle(creation) < 0 || H5Pset_deflate(creation, 4) < 0)) || H5Pset_fletcher32(creation) < 0) {
    fail_hdf5(where, "cannot set up chunked, checksummed storage");
  }
}

}  // namespace

void write_dataset(hid_t loc, const std::string& name, hid_t file_type, hid_t memory_type, const void* data,
                   const Shape& shape, bool compress, const std::string& where) {
  const Dataspace space(H5Screate_simple(static_cast<int>(shape.size()), shape.data(), nullptr));
  PropertyList creation(H5Pcreate(H5P_DATASET_CREATE));
  if (!space || !creation) fail_hdf5(where, "cannot create the dataspace " + shape_text(shape));
  H5Pset_obj_track_times(creation.get(), 0);  // reproducible bytes, see create_group
  const hsize_t elements = element_count(shape);
  if (!shape.empty() && elements > 0) {
    Shape chunk = shape;
    const hsize_t row_elements = std::max<hsize_t>(1, elements / shape[0]);
    chunk[0] = std::clamp<hsize_t>(65536 / row_elements, 1, shape[0]);
    set_chunks(creation.get(), chunk, compress && elements >= 4096, where);
  }
  Dataset dataset(H5Dcreate2(loc, name.c_str(), file_type, space.get(), H5P_DEFAULT, creation.get(), H5P_DEFAULT));
  if (!dataset) fail_hdf5(where, "cannot create the dataset");
  if (elements > 0 && H5Dwrite(dataset.get(), memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) < 0) {
    fail_hdf5(where, "cannot write the dataset");
  }
  if (dataset.close() < 0) fail_hdf5(where, "cannot write the dataset");  // the close flushes its chunks
}

Dataset create_frame_dataset(hid_t loc, const std::string& name, hid_t file_type, const Shape& frame_shape,
                             const std::string& where) {
  Shape shape{0}, max_shape{H5S_UNLIMITED}, chunk{1};
  for (const hsize_t d : frame_shape) {
    shape.push_back(d);
    max_shape.push_back(d);
    chunk.push_back(std::max<hsize_t>(d, 1));
  }
  const Dataspace space(H5Screate_simple(static_cast<int>(shape.size()), shape.data(), max_shape.data()));
  const PropertyList creation(H5Pcreate(H5P_DATASET_CREATE));
  if (!space || !creation) fail_hdf5(where, "cannot create the dataspace " + shape_text(shape));
  H5Pset_obj_track_times(creation.get(), 0);  // reproducible bytes, see create_group
  set_chunks(creation.get(), chunk, true, where);
  Dataset dataset(H5Dcreate2(loc, name.c_str(), file_type, space.get(), H5P_DEFAULT, creation.get(), H5P_DEFAULT));
  if (!dataset) fail_hdf5(where, "cannot create the dataset");
  return dataset;
}

namespace {

// Selects frames [first, first + count) of a dataset's file space; returns the memory space.
Dataspace select_frames(hid_t file_space, const Shape& shape, hsize_t first, hsize_t count, const std::string& where) {
  Shape start(shape.size(), 0), extent = shape;
  start[0] = first;
  extent[0] = count;
  if (H5Sselect_hyperslab(file_space, H5S_SELECT_SET, start.data(), nullptr, extent.data(), nullptr) < 0) {
    fail_hdf5(where, "cannot select frames");
  }
  Dataspace memory(H5Screate_simple(static_cast<int>(extent.size()), extent.data(), nullptr));
  if (!memory) fail_hdf5(where, "cannot create a memory dataspace");
  return memory;
}

}  // namespace

void append_frames(hid_t dataset, hid_t memory_type, const void* data, hsize_t count, const std::string& where) {
  if (count == 0) return;
  Shape shape = dataset_shape(dataset, where);
  if (shape.empty()) fail(where, ": expected a dataset of frames, found a scalar");
  const hsize_t first = shape[0];
  shape[0] += count;
  if (H5Dset_extent(dataset, shape.data()) < 0) fail_hdf5(where, "cannot grow the dataset");
  const Dataspace file_space(H5Dget_space(dataset));
  if (!file_space) fail_hdf5(where, "cannot read the dataset's shape");
  const Dataspace memory = select_frames(file_space.get(), shape, first, count, where);
  if (H5Dwrite(dataset, memory_type, memory.get(), file_space.get(), H5P_DEFAULT, data) < 0) {
    fail_hdf5(where, "cannot write frames");
  }
}

void read_dataset(hid_t dataset, hid_t memory_type, void* out, const std::string& where) {
  if (element_count(dataset_shape(dataset, where)) == 0) return;
  if (H5Dread(dataset, memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, out) < 0) fail_hdf5(where, "cannot read");
}

void read_frames(hid_t dataset, hsize_t first, hsize_t count, hid_t memory_type, void* out, const std::string& where) {
  const Shape shape = dataset_shape(dataset, where);
  if (shape.empty()) fail(where, ": expected a dataset of frames, found a scalar");
  if (first + count > shape[0]) {
    fail(where, ": expected frames within [0, ", shape[0], "), asked for [", first, ", ", first + count, ")");
  }
  if (count == 0 || element_count(shape) == 0) return;
  const Dataspace file_space(H5Dget_space(dataset));
  if (!file_space) fail_hdf5(where, "cannot read the dataset's shape");
  const Dataspace memory = select_frames(file_space.get(), shape, first, count, where);
  if (H5Dread(dataset, memory_type, memory.get(), file_space.get(), H5P_DEFAULT, out) < 0) {
    fail_hdf5(where, "cannot read frames");
  }
}

// === Verification

namespace {

struct VerifyState {
  std::string where;
  std::vector<uint8_t> buffer;
  int64_t datasets = 0;
  std::string error;  // the first failure; the callback must not throw through HDF5's C frames
};

void verify_object(hid_t group, const char* name, VerifyState& state) {
  const std::string at = state.where + ": /" + name;
  const Object object(H5Oopen(group, name, H5P_DEFAULT));
  if (!object) fail_hdf5(at, "cannot open (damaged object header?)");
  if (H5Iget_type(object.get()) != H5I_DATASET) return;
  const Datatype type(H5Dget_type(object.get()));
  if (!type) fail_hdf5(at, "cannot read the element type");
  if (H5Tis_variable_str(type.get()) > 0 || H5Tdetect_class(type.get(), H5T_VLEN) > 0) return;  // none in amt files
  const Shape shape = dataset_shape(object.get(), at);
  state.buffer.resize(size_t(element_count(shape)) * H5Tget_size(type.get()));
  if (!state.buffer.empty() &&
      H5Dread(object.get(), type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, state.buffer.data()) < 0) {
    fail_hdf5(at, "damaged data (its checksum or compressed stream does not match)");
  }
  ++state.datasets;
}

herr_t verify_link(hid_t group, const char* name, const H5L_info_t* info, void* data) {
  auto& state = *static_cast<VerifyState*>(data);
  if (info->type != H5L_TYPE_HARD) return 0;
  try {
    verify_object(group, name, state);
  } catch (const std::exception& e) {
    state.error = e.what();
    return 1;  // stops the walk
  }
  return 0;
}

}  // namespace

int64_t verify_datasets(hid_t file, const std::string& where) {
  VerifyState state{where, {}, 0, {}};
  const herr_t status = H5Lvisit(file, H5_INDEX_NAME, H5_ITER_NATIVE, verify_link, &state);
  if (!state.error.empty()) {
    H5Eclear2(H5E_DEFAULT);
    throw Error(state.error);
  }
  if (status < 0) fail_hdf5(where, "cannot walk the file's objects (damaged file?)");
  return state.datasets;
}

}  // namespace amt::h5
