#pragma once
// RAII owners of HDF5 C API ids and the few typed read/write helpers the dataset file
// (data_tools/formats/dataset_file.h) is built from. Internal to amt_formats: this header includes
// <hdf5.h>, whose include directories are private to the library; public headers must not include it.
//
// Every helper throws amt::Error with a one-line message that starts with `where`, the file and
// object being read or written ("x.h5: /characters/bob/faces"), and ends with the innermost
// message of HDF5's error stack when HDF5 itself failed.
#include <hdf5.h>

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace amt::h5 {

// === Handles

/// Unique owner of one HDF5 id, released with `Close` (H5Fclose, H5Gclose, ...). Move-only; an
/// empty handle holds H5I_INVALID_HID. One alias per id kind below, so a group cannot be closed as
/// a dataset.
template <herr_t (*Close)(hid_t)>
class Handle {
 public:
  Handle() = default;
  /// Takes ownership of `id` (a negative id, as returned by a failed HDF5 call, stays empty).
  explicit Handle(hid_t id) : id_(id) {}
  ~Handle() { reset(); }
  Handle(Handle&& other) noexcept : id_(std::exchange(other.id_, H5I_INVALID_HID)) {}
  Handle& operator=(Handle&& other) noexcept {
    if (this != &other) {
      reset();
      id_ = std::exchange(other.id_, H5I_INVALID_HID);
    }
    return *this;
  }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;

  /// The owned id (still owned by this handle).
  hid_t get() const { return id_; }
  /// True when the handle owns a valid id.
  bool valid() const { return id_ >= 0; }
  explicit operator bool() const { return valid(); }
  /// Closes the owned id now and returns Close's status (0 when the handle was empty).
  herr_t close() {
    herr_t status = 0;
    if (id_ >= 0) status = Close(id_);
    id_ = H5I_INVALID_HID;
    return status;
  }
  /// Closes the owned id, ignoring failures (as the destructor does).
  void reset() { close(); }

 private:
  hid_t id_ = H5I_INVALID_HID;
};

using File = Handle<&H5Fclose>;
using Group = Handle<&H5Gclose>;
using Dataset = Handle<&H5Dclose>;
using Dataspace = Handle<&H5Sclose>;
using Datatype = Handle<&H5Tclose>;
using PropertyList = Handle<&H5Pclose>;
using Attribute = Handle<&H5Aclose>;
/// Any object opened with H5Oopen.
using Object = Handle<&H5Oclose>;

// === Errors

/// Turns off HDF5's automatic printing of its error stack to stderr on this thread for the guard's
/// lifetime and restores the previous handler afterwards (the setting is per thread in thread-safe
/// builds). Every public entry point that calls HDF5 holds one, so that a failure is reported once,
/// as the amt::Error line.
class QuietErrors {
 public:
  QuietErrors();
  ~QuietErrors();
  QuietErrors(const QuietErrors&) = delete;
  QuietErrors& operator=(const QuietErrors&) = delete;

 private:
  H5E_auto2_t previous_function_ = nullptr;
  void* previous_data_ = nullptr;
};

/// The innermost description on this thread's HDF5 error stack (e.g. "truncated file: eof = 1024,
/// sblock->base_addr = 0, stored_eof = 2048"), or "" when the stack is empty.
std::string last_error_message();

/// Throws amt::Error "<where>: <what>[: <innermost HDF5 error>]".
[[noreturn]] void fail_hdf5(const std::string& where, const std::string& what);

// === Files and groups

/// True when `path` is a readable file that starts like an HDF5 file (its signature); a truncated
/// HDF5 file still passes, and fails in open_file.
bool is_hdf5_file(const std::string& path);

/// Creates (truncating) an HDF5 file for writing. Closing the returned handle closes every object
/// still open in it (strong close degree).
File create_file(const std::string& path, const std::string& where);

/// Opens an existing HDF5 file, read-only or for writing, with the strong close degree.
File open_file(const std::string& path, bool writable, const std::string& where);

/// True when `loc` has a direct child link called `name`.
bool has_child(hid_t loc, const std::string& name);

/// Creates the group `name` under `loc`.
Group create_group(hid_t loc, const std::string& name, const std::string& where);

/// Opens the group `name` under `loc`; throws "<where>: missing (expected <expected>)" when absent.
Group open_group(hid_t loc, const std::string& name, const std::string& where, const std::string& expected);

/// Names of the direct children of a group, sorted by name.
std::vector<std::string> child_names(hid_t group, const std::string& where);

// === Attributes (scalars and 1-D string lists on a file, group or dataset)

/// True when the object `obj` has an attribute `name`.
bool has_attribute(hid_t obj, const std::string& name);

/// Writes a scalar variable-length UTF-8 string attribute.
void write_string_attribute(hid_t obj, const std::string& name, const std::string& value, const std::string& where);

/// Writes a 1-D attribute of variable-length UTF-8 strings.
void write_string_list_attribute(hid_t obj, const std::string& name, const std::vector<std::string>& values,
                                 const std::string& where);

/// Writes a scalar float32 attribute.
void write_float_attribute(hid_t obj, const std::string& name, float value, const std::string& where);

/// Writes a scalar int32 attribute.
void write_int_attribute(hid_t obj, const std::string& name, int32_t value, const std::string& where);

/// Reads a string attribute (fixed or variable length, scalar or one element). `where` names the
/// object; messages read "<where>: attribute '<name>': missing (expected a string)".
std::string read_string_attribute(hid_t obj, const std::string& name, const std::string& where);

/// Reads a 1-D string-list attribute (fixed or variable length strings).
std::vector<std::string> read_string_list_attribute(hid_t obj, const std::string& name, const std::string& where);

/// Reads a numeric attribute (any integer or float type, one element) as float.
float read_float_attribute(hid_t obj, const std::string& name, const std::string& where);

/// Reads an integer attribute (any integer type, one element).
int64_t read_int_attribute(hid_t obj, const std::string& name, const std::string& where);

// === Datasets

/// A dataspace shape, outermost dimension first.
using Shape = std::vector<hsize_t>;

/// "(10,3)" for {10, 3}; "()" for a scalar.
std::string shape_text(const Shape& shape);

/// Memory type of the element types the project stores: float, int32_t, uint8_t.
template <typename T>
hid_t memory_type();
template <>
inline hid_t memory_type<float>() {
  return H5T_NATIVE_FLOAT;
}
template <>
inline hid_t memory_type<int32_t>() {
  return H5T_NATIVE_INT32;
}
template <>
inline hid_t memory_type<uint8_t>() {
  return H5T_NATIVE_UINT8;
}

/// Little-endian file type stored for float, int32_t and uint8_t elements.
template <typename T>
hid_t file_type();
template <>
inline hid_t file_type<float>() {
  return H5T_IEEE_F32LE;
}
template <>
inline hid_t file_type<int32_t>() {
  return H5T_STD_I32LE;
}
template <>
inline hid_t file_type<uint8_t>() {
  return H5T_STD_U8LE;
}

/// Opens the dataset `name` under `loc`; throws "<where>: missing (expected dataset <expected>)"
/// when absent, or "<where>: expected dataset <expected>, found a group" when it is something else.
Dataset open_dataset(hid_t loc, const std::string& name, const std::string& where, const std::string& expected);

/// Current shape of a dataset.
Shape dataset_shape(hid_t dataset, const std::string& where);

/// HDF5 type class of a dataset's elements (H5T_FLOAT, H5T_INTEGER, H5T_STRING, ...).
H5T_class_t element_class(hid_t dataset, const std::string& where);

/// Readable name of a dataset's element type: "float32", "int64", "uint8", "string", ...
std::string element_type_name(hid_t dataset);

/// Writes a whole dataset of `shape` from `data` (row-major, product(shape) elements of
/// `memory_type`) stored as `file_type`, chunked along dimension 0 (about 64k elements a chunk) with
/// a Fletcher-32 checksum of each chunk that reads verify. With `compress`, arrays of 4096 elements
/// or more are also compressed (shuffle + deflate 4).
void write_dataset(hid_t loc, const std::string& name, hid_t file_type, hid_t memory_type, const void* data,
                   const Shape& shape, bool compress, const std::string& where);

/// Typed form of write_dataset for float, int32_t and uint8_t.
template <typename T>
void write_dataset(hid_t loc, const std::string& name, const T* data, const Shape& shape, bool compress,
                   const std::string& where) {
  write_dataset(loc, name, file_type<T>(), memory_type<T>(), data, shape, compress, where);
}

/// Creates an empty dataset of frames: shape (0, frame_shape...), dimension 0 extendible without
/// limit, one frame per chunk, compressed with shuffle + deflate level 4 and checksummed.
Dataset create_frame_dataset(hid_t loc, const std::string& name, hid_t file_type, const Shape& frame_shape,
                             const std::string& where);

/// Grows dimension 0 of a dataset by `count` frames and writes them from `data` (count frames of
/// product(frame shape) elements of `memory_type`, frame-major).
void append_frames(hid_t dataset, hid_t memory_type, const void* data, hsize_t count, const std::string& where);

/// Reads a whole dataset into `out` (product(shape) elements of `memory_type`), converting types.
void read_dataset(hid_t dataset, hid_t memory_type, void* out, const std::string& where);

/// Reads frames [first, first + count) along dimension 0 (a hyperslab; nothing else is read) into
/// `out` (count * product(shape[1:]) elements of `memory_type`).
void read_frames(hid_t dataset, hsize_t first, hsize_t count, hid_t memory_type, void* out, const std::string& where);

/// Reads every dataset of the file in full, so that HDF5 verifies each chunk's checksum (Fletcher-32
/// in files written since dataset version 2) and each compressed stream (zlib's Adler-32 in every
/// file), and the metadata on the way. Throws amt::Error "where: /path: damaged data ..." at the
/// first failure; returns the number of datasets read.
int64_t verify_datasets(hid_t file, const std::string& where);

}  // namespace amt::h5
