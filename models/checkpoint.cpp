#include "models/checkpoint.h"

#include <torch/serialize/input-archive.h>
#include <torch/serialize/output-archive.h>
#include <torch/utils.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <sstream>

#include "data_tools/formats/atomic_file.h"
#include "data_tools/formats/checksum_torch.h"
#include "data_tools/formats/input_file.h"
#include "data_tools/formats/temporary_registry.h"
#include "data_tools/geometry/error.h"
#include "models/module_options.h"

namespace amt {
namespace {

// The first line of an exception message (c10::Error messages carry a stack trace after it).
std::string first_line(const std::exception& e) {
  const std::string what = e.what();
  return what.substr(0, what.find('\n'));
}

// "a, b, c" of at most `limit` names, then ", ..." when there are more.
std::string name_list(const std::vector<std::string>& names, size_t limit = 6) {
  std::ostringstream out;
  for (size_t i = 0; i < names.size() && i < limit; ++i) out << (i ? ", " : "") << names[i];
  if (names.size() > limit) out << ", ...";
  return out.str();
}

c10::IValue read_key(torch::serialize::InputArchive& archive, const std::string& path, const std::string& key) {
  c10::IValue value;
  AMT_CHECK(archive.try_read(key, value), path, ": ", key, ": missing (not an amt checkpoint?)");
  return value;
}

std::string read_string(torch::serialize::InputArchive& archive, const std::string& path, const std::string& key) {
  const c10::IValue value = read_key(archive, path, key);
  AMT_CHECK(value.isString(), path, ": ", key, ": expected a string, found ", value.tagKind());
  return value.toStringRef();
}

int64_t read_int(torch::serialize::InputArchive& archive, const std::string& path, const std::string& key) {
  const c10::IValue value = read_key(archive, path, key);
  AMT_CHECK(value.isInt(), path, ": ", key, ": expected an integer, found ", value.tagKind());
  return value.toInt();
}

// A list of strings under `key` (`label` names it in messages: a nested key reads "model/...").
std::vector<std::string> read_names(torch::serialize::InputArchive& archive, const std::string& path,
                                    const std::string& label, const std::string& key) {
  c10::IValue value;
  AMT_CHECK(archive.try_read(key, value), path, ": ", label, ": missing (not an amt checkpoint?)");
  AMT_CHECK(value.isList(), path, ": ", label, ": expected a list of strings, found ", value.tagKind());
  std::vector<std::string> names;
  for (const c10::IValue& name : value.toListRef()) {
    AMT_CHECK(name.isString(), path, ": ", label, ": expected a list of strings, found an entry ", name.tagKind());
    names.push_back(name.toStringRef());
  }
  return names;
}

void open_archive(torch::serialize::InputArchive& archive, const std::string& path) {
  check_input_file(path, "an amt checkpoint");
  try {
    archive.load_from(path);
  } catch (const std::exception& e) {
    fail(path, ": not an amt checkpoint (", first_line(e), ")");
  }
}

// CRC-32 of a checkpoint's payload: its module kind, options, config, step, data fingerprint, joint
// names and the model's tensors in their stored order (parameters, then buffers). The optimizer state
// is not covered.
uint32_t payload_crc32(const CheckpointInfo& info, const std::vector<at::Tensor>& tensors) {
  uint32_t crc = crc32_update(0, module_kind_name(info.kind));
  for (const std::string* text : {&info.options_json, &info.config_json, &info.data_fingerprint}) {
    crc = crc32_update(crc, *text);
  }
  crc = crc32_update(crc, &info.step, sizeof(info.step));
  for (const std::string& name : info.joint_names) crc = crc32_update(crc, name);
  for (const at::Tensor& t : tensors) crc = crc32_update(crc, t);
  return crc;
}

// Reads and checks the keys other than model/ and optimizer/.
CheckpointInfo read_info(torch::serialize::InputArchive& archive, const std::string& path,
                         std::optional<ModuleKind> expected_kind) {
  const std::string format = read_string(archive, path, "format");
  AMT_CHECK(format == kCheckpointFormat, path, ": format: expected '", kCheckpointFormat, "', found '", format, "'");
  const int64_t version = read_int(archive, path, "version");
  AMT_CHECK(version == kCheckpointVersion, path, ": version: expected ", kCheckpointVersion, ", found ", version,
            version > kCheckpointVersion ? " (written by a newer amt)" : "");
  CheckpointInfo info;
  info.kind = parse_module_kind(read_string(archive, path, "kind"), path + ": kind");
  if (expected_kind) {
    AMT_CHECK(info.kind == *expected_kind, path, ": kind: expected '", module_kind_name(*expected_kind), "', found '",
              module_kind_name(info.kind), "'");
  }
  info.options_json = read_string(archive, path, "options");
  info.config_json = read_string(archive, path, "config");
  info.step = read_int(archive, path, "step");
  AMT_CHECK(info.step >= 0, path, ": step: expected >= 0, found ", info.step);
  info.data_fingerprint = read_string(archive, path, "data_fingerprint");
  info.joint_names = read_names(archive, path, "joint_names", "joint_names");
  c10::IValue crc;
  info.checksummed = archive.try_read("payload_crc32", crc);
  at::Tensor optimizer_bytes;
  torch::serialize::InputArchive optimizer_archive;
  info.has_optimizer =
      archive.try_read("optimizer_bytes", optimizer_bytes) || archive.try_read("optimizer", optimizer_archive);
  return info;
}

// The model is stored flat: lists of the qualified parameter and buffer names, and the tensors under
// the keys p<i> and b<i>. (Module::save uses submodule names as TorchScript attribute names, so a
// submodule named after a Python keyword would make its archive unreadable; this form does not care.)
// Returns the tensors written, in order, for the payload checksum.
std::vector<at::Tensor> write_model(torch::serialize::OutputArchive& archive, const torch::nn::Module& model) {
  c10::List<std::string> parameter_names, buffer_names;
  std::vector<at::Tensor> written;
  int64_t i = 0;
  for (const auto& p : model.named_parameters()) {
    parameter_names.push_back(p.key());
    written.push_back(p.value().detach());
    archive.write("p" + std::to_string(i++), written.back());
  }
  i = 0;
  for (const auto& b : model.named_buffers()) {
    buffer_names.push_back(b.key());
    written.push_back(b.value().detach());
    archive.write("b" + std::to_string(i++), written.back(), /*is_buffer=*/true);
  }
  archive.write("parameter_names", c10::IValue(parameter_names));
  archive.write("buffer_names", c10::IValue(buffer_names));
  return written;
}

// Copies the stored tensors into the model's own (so optimizers keep pointing at them), checking
// that names and shapes agree with the network built from the checkpoint's options. Returns the
// stored tensors, in order, for the payload checksum.
std::vector<at::Tensor> read_model(torch::serialize::InputArchive& archive, const std::string& path,
                                   torch::nn::Module& model) {
  std::vector<at::Tensor> read;
  const auto copy_all = [&](const std::string& kind, const std::string& prefix,
                            const torch::OrderedDict<std::string, at::Tensor>& tensors, bool is_buffer) {
    const std::vector<std::string> names = read_names(archive, path, "model/" + kind + "_names", kind + "_names");
    AMT_CHECK(names.size() == tensors.size(), path, ": model: expected ", tensors.size(), " ", kind, "s, found ",
              names.size(), " (a network of other options?)");
    for (size_t i = 0; i < names.size(); ++i) {
      const std::string& name = tensors.items()[i].key();
      const at::Tensor& tensor = tensors.items()[i].value();
      AMT_CHECK(names[i] == name, path, ": model: ", kind, " ", i, ": expected '", name, "', found '", names[i], "'");
      at::Tensor stored;
      AMT_CHECK(archive.try_read(prefix + std::to_string(i), stored, is_buffer), path, ": model: ", name, ": missing");
      AMT_CHECK(stored.sizes() == tensor.sizes(), path, ": model: ", name, ": expected shape ", tensor.sizes(),
                ", found ", stored.sizes());
      torch::NoGradGuard no_grad;
      at::Tensor(tensor).copy_(stored);
      read.push_back(stored);
    }
  };
  copy_all("parameter", "p", model.named_parameters(), false);
  copy_all("buffer", "b", model.named_buffers(), true);
  return read;
}

}  // namespace

const char* module_kind_name(ModuleKind kind) {
  switch (kind) {
    case ModuleKind::kSegmenter:
      return "segmenter";
    case ModuleKind::kSkinning:
      return "skinning";
    case ModuleKind::kApparel:
      return "apparel";
    case ModuleKind::kRefiner:
      return "refiner";
  }
  return "unknown";
}

ModuleKind parse_module_kind(const std::string& name, const std::string& source) {
  for (ModuleKind kind : {ModuleKind::kSegmenter, ModuleKind::kSkinning, ModuleKind::kApparel, ModuleKind::kRefiner}) {
    if (name == module_kind_name(kind)) return kind;
  }
  fail(source, ": expected segmenter, skinning, apparel or refiner, found '", name, "'");
}

void save_checkpoint(const std::string& path, const CheckpointInfo& info, const torch::nn::Module& model,
                     const torch::optim::Optimizer* optimizer, const std::vector<at::Tensor>* training_parameters) {
  torch::serialize::OutputArchive archive;
  archive.write("format", c10::IValue(std::string(kCheckpointFormat)));
  archive.write("version", c10::IValue(kCheckpointVersion));
  archive.write("kind", c10::IValue(std::string(module_kind_name(info.kind))));
  archive.write("options", c10::IValue(info.options_json));
  archive.write("config", c10::IValue(info.config_json));
  archive.write("step", c10::IValue(info.step));
  archive.write("data_fingerprint", c10::IValue(info.data_fingerprint));
  c10::List<std::string> names;
  for (const auto& name : info.joint_names) names.push_back(name);
  archive.write("joint_names", c10::IValue(names));

  torch::serialize::OutputArchive model_archive(archive.compilation_unit());
  const std::vector<at::Tensor> written = write_model(model_archive, model);
  archive.write("model", model_archive);
  archive.write("payload_crc32", c10::IValue(int64_t(payload_crc32(info, written))));
  if (optimizer) {
    // The optimizer's state as the bytes of its own archive under a CRC-32 (optimizer_crc32), so that a damaged
    // moment estimate is found on --resume instead of resuming to a diverging loss.
    torch::serialize::OutputArchive optimizer_archive;
    optimizer->save(optimizer_archive);
    std::ostringstream bytes;
    optimizer_archive.save_to(bytes);
    const std::string text = bytes.str();
    at::Tensor blob = at::empty({int64_t(text.size())}, at::kByte);
    std::memcpy(blob.data_ptr<uint8_t>(), text.data(), text.size());
    archive.write("optimizer_bytes", blob);
    archive.write("optimizer_crc32", c10::IValue(int64_t(crc32_update(0, text.data(), text.size()))));
  }
  if (training_parameters) {
    torch::serialize::OutputArchive training_archive(archive.compilation_unit());
    uint32_t crc = 0;
    for (size_t i = 0; i < training_parameters->size(); ++i) {
      const at::Tensor t = (*training_parameters)[i].detach();
      training_archive.write("t" + std::to_string(i), t);
      crc = crc32_update(crc, t);
    }
    training_archive.write("count", c10::IValue(int64_t(training_parameters->size())));
    archive.write("training_parameters", training_archive);
    archive.write("training_parameters_crc32", c10::IValue(int64_t(crc)));
  }

  save_archive_atomically(archive, path, "checkpoint");
}

void save_archive_atomically(torch::serialize::OutputArchive& archive, const std::string& path,
                             const std::string& what) {
  create_parent_folder(path);
  check_replaceable_file(path);
  const std::string temporary = temporary_path(path);
  prepare_temporary_file(temporary);
  register_temporary(temporary);
  std::FILE* out = std::fopen(temporary.c_str(), "wb");
  if (out == nullptr) {
    const int error = errno;
    discard_temporary(temporary);
    fail(temporary, ": cannot create the ", what, " (", std::strerror(error), ")");
  }
  // LibTorch's zip writer throws c10::Error from its destructor when a write fails, which ends the
  // process in std::terminate. So it writes through a function that always reports success, and the
  // first write error is kept here and reported once the archive is complete.
  int write_error = 0;
  try {
    archive.save_to([&](const void* data, size_t size) -> size_t {
      if (write_error == 0 && size > 0 && std::fwrite(data, 1, size, out) != size) write_error = errno ? errno : EIO;
      return size;
    });
  } catch (const std::exception& e) {
    std::fclose(out);
    discard_temporary(temporary);
    fail(temporary, ": cannot write the ", what, " (", first_line(e), ")");
  }
  if (std::fflush(out) != 0 && write_error == 0) write_error = errno ? errno : EIO;
  if (std::fclose(out) != 0 && write_error == 0) write_error = errno ? errno : EIO;
  if (write_error != 0) {
    discard_temporary(temporary);
    fail(temporary, ": write: expected the whole ", what, " written, found an error (", std::strerror(write_error),
         ")");
  }
  replace_with_temporary(temporary, path);
}

CheckpointInfo read_checkpoint_info(const std::string& path, std::optional<ModuleKind> expected_kind) {
  torch::serialize::InputArchive archive;
  open_archive(archive, path);
  return read_info(archive, path, expected_kind);
}

CheckpointInfo load_checkpoint(const std::string& path, ModuleKind expected_kind, torch::nn::Module& model,
                               torch::optim::Optimizer* optimizer, std::vector<at::Tensor>* training_parameters) {
  torch::serialize::InputArchive archive;
  open_archive(archive, path);
  CheckpointInfo info = read_info(archive, path, expected_kind);

  torch::serialize::InputArchive model_archive;
  AMT_CHECK(archive.try_read("model", model_archive), path, ": model: missing");
  const std::vector<at::Tensor> stored = read_model(model_archive, path, model);
  // Checkpoints written before the checksum have no payload_crc32 and load unverified.
  c10::IValue crc;
  if (archive.try_read("payload_crc32", crc)) {
    AMT_CHECK(crc.isInt(), path, ": payload_crc32: expected an integer, found ", crc.tagKind());
    const uint32_t computed = payload_crc32(info, stored);
    AMT_CHECK(int64_t(computed) == crc.toInt(), path, ": payload_crc32: expected ", crc.toInt(),
              " (the CRC-32 stored with the parameters and options), found ", computed,
              " over what was read: the file is damaged");
  }

  if (optimizer) {
    torch::serialize::InputArchive optimizer_archive;
    at::Tensor blob;
    if (archive.try_read("optimizer_bytes", blob)) {
      c10::IValue stored;
      AMT_CHECK(archive.try_read("optimizer_crc32", stored) && stored.isInt(), path,
                ": optimizer_crc32: expected an integer, found none");
      AMT_CHECK(blob.dim() == 1 && blob.scalar_type() == at::kByte, path,
                ": optimizer_bytes: expected a 1-D byte tensor, found ", blob.sizes(), " ", blob.scalar_type());
      blob = blob.contiguous();
      const std::string text(reinterpret_cast<const char*>(blob.data_ptr<uint8_t>()), size_t(blob.numel()));
      const uint32_t computed = crc32_update(0, text.data(), text.size());
      AMT_CHECK(int64_t(computed) == stored.toInt(), path, ": optimizer_crc32: expected ", stored.toInt(), ", found ",
                computed, " over the optimizer's state: the file is damaged");
      std::istringstream in(text);
      try {
        optimizer_archive.load_from(in);
      } catch (const std::exception& e) {
        fail(path, ": optimizer_bytes: expected the optimizer's archive, found ", first_line(e));
      }
    } else {
      // Checkpoints written before optimizer_crc32 keep the optimizer as a nested archive, unverified.
      AMT_CHECK(archive.try_read("optimizer", optimizer_archive), path,
                ": optimizer: missing (a model-only checkpoint cannot resume training)");
    }
    try {
      optimizer->load(optimizer_archive);
    } catch (const std::exception& e) {
      fail(path, ": optimizer: does not match the model's parameters (", first_line(e), ")");
    }
  }
  if (training_parameters) {
    training_parameters->clear();
    torch::serialize::InputArchive training_archive;
    if (archive.try_read("training_parameters", training_archive)) {
      const std::vector<at::Tensor> parameters = model.parameters();
      c10::IValue count;
      AMT_CHECK(training_archive.try_read("count", count) && count.isInt(), path,
                ": training_parameters/count: expected an integer, found none");
      AMT_CHECK(count.toInt() == int64_t(parameters.size()), path, ": training_parameters: expected ",
                parameters.size(), " tensors (the model's parameters), found ", count.toInt());
      uint32_t crc = 0;
      for (size_t i = 0; i < parameters.size(); ++i) {
        at::Tensor t;
        AMT_CHECK(training_archive.try_read("t" + std::to_string(i), t), path, ": training_parameters: t", i,
                  ": missing");
        AMT_CHECK(t.sizes() == parameters[i].sizes(), path, ": training_parameters: t", i, ": expected shape ",
                  parameters[i].sizes(), ", found ", t.sizes());
        crc = crc32_update(crc, t);
        training_parameters->push_back(t);
      }
      c10::IValue stored;
      AMT_CHECK(archive.try_read("training_parameters_crc32", stored) && stored.isInt(), path,
                ": training_parameters_crc32: expected an integer, found none");
      AMT_CHECK(int64_t(crc) == stored.toInt(), path, ": training_parameters_crc32: expected ", stored.toInt(),
                ", found ", crc, " over what was read: the file is damaged");
    }
  }
  return info;
}

template <typename Net, typename Options>
Net load_frozen_network(const std::string& path, ModuleKind kind, CheckpointInfo& info) {
  info = read_checkpoint_info(path, kind);
  Options options;
  options_from_json(info.options_json, path, options);
  Net net(options);
  load_checkpoint(path, kind, *net, nullptr);
  net->eval();
  for (auto& p : net->parameters()) p.set_requires_grad(false);
  return net;
}

// The networks load_frozen_network is defined for (models/checkpoint.h).
template ApparelSegmenter load_frozen_network<ApparelSegmenter, ApparelSegmenterOptions>(const std::string& path,
                                                                                         ModuleKind kind,
                                                                                         CheckpointInfo& info);
template SkinningPredictor load_frozen_network<SkinningPredictor, SkinningPredictorOptions>(const std::string& path,
                                                                                            ModuleKind kind,
                                                                                            CheckpointInfo& info);
template ApparelDisplacementNet load_frozen_network<ApparelDisplacementNet, ApparelDisplacementOptions>(
    const std::string& path, ModuleKind kind, CheckpointInfo& info);
template ApparelDynamicsNet load_frozen_network<ApparelDynamicsNet, ApparelDynamicsOptions>(const std::string& path,
                                                                                            ModuleKind kind,
                                                                                            CheckpointInfo& info);
template JointRefiner load_frozen_network<JointRefiner, JointRefinerOptions>(const std::string& path, ModuleKind kind,
                                                                             CheckpointInfo& info);

void check_checkpoint_skeleton(const std::string& path, const CheckpointInfo& info,
                               const std::vector<std::string>& dataset_joint_names) {
  AMT_CHECK(info.joint_names == dataset_joint_names, path, ": skeleton: the checkpoint was trained on ",
            info.joint_names.size(), " joints (", name_list(info.joint_names), "), the dataset has ",
            dataset_joint_names.size(), " (", name_list(dataset_joint_names), ")");
}

}  // namespace amt
