#include "train/distributed.h"

// ProcessGroupGloo.hpp needs USE_C10D_GLOO, which the Torch CMake target defines, and Gloo's headers
// (libgloo-dev); libtorch_cpu holds the code.
#include <ATen/ATen.h>
#include <torch/csrc/distributed/c10d/FileStore.hpp>
#include <torch/csrc/distributed/c10d/PrefixStore.hpp>
#include <torch/csrc/distributed/c10d/ProcessGroupGloo.hpp>
#include <glog/logging.h>  // c10's logging, which c10d's socket code writes to

#include <algorithm>
#include <chrono>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include "data_tools/geometry/error.h"
#include "train/rendezvous_store.h"

namespace amt {
namespace {

using Clock = std::chrono::steady_clock;

// The first line of an exception's message (c10::Error appends a backtrace on further lines).
std::string first_line(const std::string& text) {
  std::string line = text.substr(0, text.find('\n'));
  while (!line.empty() && (line.back() == ' ' || line.back() == '\r')) line.pop_back();
  return line;
}

// A whole decimal number in [low, high], or false.
bool parse_int(const std::string& text, long long low, long long high, long long& out) {
  if (text.empty() || text.size() > 18) return false;
  for (size_t i = 0; i < text.size(); ++i) {
    if (!(std::isdigit(static_cast<unsigned char>(text[i])) || (i == 0 && text[i] == '-' && text.size() > 1)))
      return false;
  }
  out = std::stoll(text);
  return out >= low && out <= high;
}

std::string seconds_text(double seconds) {
  std::ostringstream out;
  out << seconds << " s";
  return out.str();
}

}  // namespace

// === Options

Rendezvous parse_rendezvous(const std::string& url) {
  const auto bad = [&] {
    fail("--rendezvous: expected tcp://HOST:PORT (rank 0's address and a free port) or file://PATH (a file every ",
         "rank sees), found '", url, "'");
  };
  Rendezvous r;
  const size_t scheme_end = url.find("://");
  if (scheme_end == std::string::npos) bad();
  r.scheme = url.substr(0, scheme_end);
  const std::string rest = url.substr(scheme_end + 3);
  if (r.scheme == "file") {
    if (rest.empty()) bad();
    r.path = rest;
    return r;
  }
  if (r.scheme != "tcp") bad();
  // HOST:PORT, or [IPv6]:PORT.
  size_t colon = rest.rfind(':');
  if (colon == std::string::npos || colon == 0) bad();
  r.host = rest.substr(0, colon);
  if (r.host.size() >= 2 && r.host.front() == '[' && r.host.back() == ']') r.host = r.host.substr(1, r.host.size() - 2);
  if (r.host.empty() || r.host.find_first_of("/[]") != std::string::npos) bad();
  long long port = 0;
  if (!parse_int(rest.substr(colon + 1), 1, 65535, port)) bad();
  r.port = static_cast<int>(port);
  return r;
}

DistributedOptions resolve_distributed_options(DistributedOptions given,
                                               const std::function<const char*(const char*)>& getenv) {
  const auto env = [&](const char* name) -> std::string {
    const char* value = getenv(name);
    return value ? std::string(value) : std::string();
  };
  DistributedOptions o = given;
  // Where each value came from, for the messages: the option or the environment variable.
  std::string world_from = "--world-size", rank_from = "--rank";
  if (given.world_size <= 0) {
    o.world_size = 1;
    if (const std::string w = env("WORLD_SIZE"); !w.empty()) {
      long long value = 0;
      AMT_CHECK(parse_int(w, 1, 1 << 20, value), "WORLD_SIZE: expected the number of ranks, an integer >= 1, found '",
                w, "'");
      o.world_size = static_cast<int>(value);
      world_from = "WORLD_SIZE";
    }
  }
  bool rank_given = given.rank >= 0;
  if (!rank_given) {
    o.rank = 0;
    if (const std::string r = env("RANK"); !r.empty()) {
      long long value = 0;
      AMT_CHECK(parse_int(r, 0, std::numeric_limits<int>::max(), value),
                "RANK: expected this process's rank, an integer >= 0, found '", r, "'");
      o.rank = static_cast<int>(value);
      rank_from = "RANK";
      rank_given = true;
    }
  }
  AMT_CHECK(o.world_size >= 1, world_from, ": expected the number of ranks, >= 1, found ", o.world_size);
  AMT_CHECK(o.rank < o.world_size, rank_from, " ", o.rank, ": expected a rank in [0, ", o.world_size, ") (",
            world_from, " ", o.world_size, ")");
  AMT_CHECK(o.timeout_seconds > 0 && std::isfinite(o.timeout_seconds), "--dist-timeout: expected seconds > 0, found ",
            o.timeout_seconds);
  if (o.world_size == 1) return o;
  AMT_CHECK(rank_given, rank_from, ": expected this process's rank in [0, ", o.world_size, ") with ", world_from, " ",
            o.world_size, ", found none (give --rank or set RANK)");
  std::string token_from = "--dist-token";
  if (o.token.empty()) {
    o.token = env("AMT_DIST_TOKEN");
    token_from = "AMT_DIST_TOKEN";
  }
  if (!o.token.empty()) check_token(o.token, token_from);
  if (o.rendezvous.empty()) {
    const std::string address = env("MASTER_ADDR"), port = env("MASTER_PORT");
    AMT_CHECK(!address.empty() || !port.empty(), "--rendezvous: expected tcp://HOST:PORT or file://PATH with ",
              world_from, " ", o.world_size, ", found none (give --rendezvous or set MASTER_ADDR and MASTER_PORT)");
    AMT_CHECK(!address.empty(), "MASTER_ADDR: expected rank 0's address along with MASTER_PORT ", port,
              ", found none");
    long long value = 0;
    AMT_CHECK(parse_int(port, 1, 65535, value), "MASTER_PORT: expected a port in [1, 65535] along with MASTER_ADDR ",
              address, ", found '", port, "'");
    const bool ipv6 = address.find(':') != std::string::npos;
    o.rendezvous = "tcp://" + (ipv6 ? "[" + address + "]" : address) + ":" + port;
  }
  const Rendezvous rendezvous = parse_rendezvous(o.rendezvous);
  // Anyone who reaches a non-loopback address could join the run (and read and write its store) without one.
  AMT_CHECK(rendezvous.scheme != "tcp" || !o.token.empty() || is_loopback_host(rendezvous.host),
            "--dist-token: the rendezvous ", o.rendezvous,
            " is not on a loopback address, so every rank must present a shared token: give each rank the same "
            "--dist-token or AMT_DIST_TOKEN (16 to 256 characters, e.g. from `openssl rand -hex 32`)");
  return o;
}

// === Process group

struct DataParallelGroup::State {
  DistributedOptions options;
  Rendezvous rendezvous;
  std::chrono::milliseconds timeout{0};
  // file://: amt's marker, held by rank 0 while the run lives (destroyed after the store).
  std::unique_ptr<FileRendezvous> file_rendezvous;
  // Rank 0 of a loopback tcp:// run without a given token: the token it generated and the file the
  // other local ranks read it from.
  std::string generated_token, token_file;
  c10::intrusive_ptr<c10d::Store> store;
  c10::intrusive_ptr<c10d::ProcessGroupGloo> group;
  int64_t same_checks = 0;
  double communication_seconds = 0.0, allreduce_seconds = 0.0;
  int64_t communication_count = 0;
  int64_t gradient_bytes = 0;

  ~State() {
    // The token file goes while the store still holds the port, so it can only be this run's.
    if (!token_file.empty()) {
      std::error_code ignored;
      std::ifstream in(token_file);
      std::string text;
      std::getline(in, text);
      if (text == generated_token) std::filesystem::remove(token_file, ignored);
    }
  }

  // "data-parallel run tcp://host:port, rank 1 of 2".
  std::string where() const {
    return "data-parallel run " + options.rendezvous + ", rank " + std::to_string(options.rank) + " of " +
           std::to_string(options.world_size);
  }

  // Runs an exchange; a failure (a rank gone, or silent past the timeout) becomes one line naming it.
  template <typename F>
  void exchange(const std::string& what, F&& f) {
    try {
      f();
    } catch (const std::exception& e) {
      fail(where(), ": ", what, " failed: another rank stopped or did not answer within ",
           seconds_text(options.timeout_seconds), " (--dist-timeout) [", first_line(e.what()),
           "]; restart every rank with --resume from the last checkpoint");
    }
  }
};

DataParallelGroup::DataParallelGroup(const DistributedOptions& options) : state_(std::make_unique<State>()) {
  State& s = *state_;
  s.options = options;
  s.rendezvous = parse_rendezvous(options.rendezvous);
  AMT_CHECK(options.world_size >= 1 && options.rank >= 0 && options.rank < options.world_size, "--rank ", options.rank,
            ": expected a rank in [0, ", options.world_size, ")");
  s.timeout = std::chrono::milliseconds(std::max<int64_t>(1, std::llround(options.timeout_seconds * 1000.0)));
  // c10d logs its connection failures on stderr as well as throwing them; the one line amt prints names
  // them, so only fatal messages stay.
  FLAGS_minloglevel = std::max(FLAGS_minloglevel, static_cast<int32_t>(google::GLOG_FATAL));
  const bool tcp = s.rendezvous.scheme == "tcp";
  if (!tcp) {
    const std::filesystem::path folder = std::filesystem::absolute(s.rendezvous.path).parent_path();
    std::error_code error;
    AMT_CHECK(std::filesystem::is_directory(folder, error), "--rendezvous ", options.rendezvous, ": no folder ",
              folder.string(), " (expected file://PATH in a folder every rank sees)");
  }
  AMT_CHECK(!tcp || !options.token.empty() || is_loopback_host(s.rendezvous.host), "--dist-token: the rendezvous ",
            options.rendezvous, " is not on a loopback address: give every rank the same --dist-token or AMT_DIST_TOKEN");
  try {
    if (tcp) {
      RendezvousStore::Options store_options;
      store_options.host = s.rendezvous.host;
      store_options.port = s.rendezvous.port;
      store_options.serve = options.rank == 0;
      // One connection per rank, and room for strangers, who are turned away within seconds.
      store_options.max_connections = std::min(options.world_size, 4096) + 16;
      store_options.timeout = s.timeout;
      store_options.token = options.token;
      if (options.token.empty()) {
        const std::string path = local_token_path(s.rendezvous.host, s.rendezvous.port);
        if (options.rank == 0) {
          // Written once the port is bound (a rank 0 that cannot bind must not replace a live run's token)
          // and before it accepts connections (a rank that connects finds the token of this run).
          s.generated_token = generate_token();
          store_options.token = s.generated_token;
          store_options.bound = [&s, path](int) {
            write_local_token(path, s.generated_token);
            s.token_file = path;
          };
        } else {
          store_options.read_token = [path] { return read_local_token(path); };
        }
      }
      s.store = c10::make_intrusive<RendezvousStore>(store_options);
    } else {
      s.file_rendezvous = std::make_unique<FileRendezvous>(s.rendezvous.path, options.rank == 0, s.timeout);
      s.store = c10::make_intrusive<c10d::FileStore>(s.file_rendezvous->store_path(), options.world_size);
    }
    s.store->setTimeout(s.timeout);
  } catch (const RendezvousRefused& e) {
    fail(s.where(), ": ", e.what());
  } catch (const std::exception& e) {
    // FileRendezvous's refusals and timeouts are complete lines; c10d's errors are not.
    if (!tcp && dynamic_cast<const Error*>(&e)) fail(s.where(), ": ", e.what());
    if (tcp && options.rank == 0) {
      fail(s.where(), ": cannot listen on port ", s.rendezvous.port, " of ", s.rendezvous.host,
           " (--rendezvous: expected a free port on rank 0's address) [", first_line(e.what()), "]");
    }
    fail(s.where(), ": cannot reach the rendezvous within ", seconds_text(options.timeout_seconds),
         " (--rendezvous, --dist-timeout) [", first_line(e.what()), "]");
  }
  // Each rank marks its arrival, so that a rank that times out can name those that never came.
  const auto joined_key = [](int rank) { return "amt/joined/" + std::to_string(rank); };
  try {
    s.store->set(joined_key(options.rank), std::vector<uint8_t>{1});
    auto group_options = c10d::ProcessGroupGloo::Options::create(s.timeout);
    // GLOO_SOCKET_IFNAME names the network interface, as with PyTorch; a loopback rendezvous stays on
    // loopback; otherwise the address this machine's host name resolves to (loopback when it resolves
    // to none of this machine's addresses).
    if (const char* interface = std::getenv("GLOO_SOCKET_IFNAME"); interface && *interface) {
      group_options->devices.push_back(c10d::ProcessGroupGloo::createDeviceForInterface(interface));
    } else if (tcp && is_loopback_host(s.rendezvous.host)) {
      group_options->devices.push_back(c10d::ProcessGroupGloo::createDeviceForHostname("127.0.0.1"));
    } else {
      group_options->devices.push_back(c10d::ProcessGroupGloo::createDefaultDevice());
    }
    s.group = c10::make_intrusive<c10d::ProcessGroupGloo>(c10::make_intrusive<c10d::PrefixStore>("gloo", s.store),
                                                          options.rank, options.world_size, group_options);
  } catch (const std::exception& e) {
    std::string absent;
    int present = 0;
    bool looked = true;
    try {
      for (int r = 0; r < options.world_size; ++r) {
        if (!s.store->check({joined_key(r)})) {
          absent += (absent.empty() ? "" : ", ") + std::to_string(r);
        } else {
          ++present;
        }
      }
    } catch (const std::exception&) {
      absent.clear();  // the store itself is gone: the ranks cannot be told
      looked = false;
    }
    // The store of a run that failed to form is of no further use (the next rank 0 starts a new run). The
    // last rank present to have had its look removes it: a look at a removed file store creates it anew.
    // (What is left when a rank dies here, the next rank 0 removes.) Rank 0's marker goes with its State.
    if (!tcp && looked) {
      bool last = false;
      try {
        last = s.store->add("amt/looked", 1) >= present;
      } catch (const std::exception&) {
      }
      const std::string store_path = s.file_rendezvous->store_path();
      s.group.reset();
      s.store.reset();
      std::error_code ignored;
      if (last) std::filesystem::remove(store_path, ignored);
    }
    fail(s.where(), ": ", absent.empty() ? std::string("the ranks") : "rank(s) " + absent, " did not join within ",
         seconds_text(options.timeout_seconds), " (--dist-timeout; start every rank with the same --world-size ",
         options.world_size, " and --rendezvous) [", first_line(e.what()), "]");
  }
}

DataParallelGroup::~DataParallelGroup() = default;

int DataParallelGroup::rank() const { return state_->options.rank; }

int DataParallelGroup::world_size() const { return state_->options.world_size; }

void DataParallelGroup::expect_same(const std::string& what, const std::string& text) {
  State& s = *state_;
  const std::string key = "amt/same/" + std::to_string(s.same_checks++);
  if (s.options.rank == 0) {
    s.store->set(key, std::vector<uint8_t>(text.begin(), text.end()));
    return;
  }
  std::vector<uint8_t> bytes;
  s.exchange("reading rank 0's " + what, [&] { bytes = s.store->get(key); });
  const std::string theirs(bytes.begin(), bytes.end());
  AMT_CHECK(theirs == text, s.where(), ": ", what, ": expected rank 0's ", theirs, ", found ", text,
            " (every rank must run with the same settings and data)");
}

void DataParallelGroup::broadcast_from_rank0(const std::vector<at::Tensor>& tensors) {
  State& s = *state_;
  // One byte buffer holding every tensor, whatever its dtype.
  int64_t bytes = 0;
  for (const at::Tensor& t : tensors) bytes += static_cast<int64_t>(t.numel() * t.element_size());
  at::Tensor buffer = at::empty({bytes}, at::kByte);
  std::vector<at::Tensor> contiguous;
  for (const at::Tensor& t : tensors) contiguous.push_back(t.detach().contiguous());
  if (s.options.rank == 0) {
    int64_t offset = 0;
    for (const at::Tensor& t : contiguous) {
      const size_t n = static_cast<size_t>(t.numel() * t.element_size());
      std::memcpy(buffer.data_ptr<uint8_t>() + offset, t.data_ptr(), n);
      offset += static_cast<int64_t>(n);
    }
  }
  s.exchange("the broadcast of rank 0's parameters", [&] {
    std::vector<at::Tensor> list{buffer};
    s.group->broadcast(list)->wait();
  });
  int64_t offset = 0;
  for (size_t i = 0; i < tensors.size(); ++i) {
    const at::Tensor& t = contiguous[i];
    const size_t n = static_cast<size_t>(t.numel() * t.element_size());
    std::memcpy(t.data_ptr(), buffer.data_ptr<uint8_t>() + offset, n);
    offset += static_cast<int64_t>(n);
    if (!tensors[i].is_same(t)) tensors[i].detach().copy_(t);
  }
}

void DataParallelGroup::average_gradients(const std::vector<at::Tensor>& parameters, std::vector<double>& values,
                                          int64_t step) {
  State& s = *state_;
  const auto start = Clock::now();
  // The gradients as one float buffer; the values and one flag per parameter (it has a gradient) as doubles.
  std::vector<at::Tensor> parts;
  at::Tensor side = at::empty({static_cast<int64_t>(values.size() + parameters.size())}, at::kDouble);
  double* side_data = side.data_ptr<double>();
  for (size_t i = 0; i < values.size(); ++i) side_data[i] = values[i];
  for (size_t i = 0; i < parameters.size(); ++i) {
    const at::Tensor& p = parameters[i];
    AMT_CHECK(p.scalar_type() == at::kFloat, s.where(), ": parameter ", i, ": expected float32, found ",
              p.scalar_type());
    const bool has = p.grad().defined();
    side_data[values.size() + i] = has ? 1.0 : 0.0;
    parts.push_back(has ? p.grad().detach().reshape({-1}) : at::zeros({p.numel()}, at::kFloat));
  }
  at::Tensor flat = parts.empty() ? at::zeros({0}, at::kFloat) : at::cat(parts);
  // The small exchange first: it absorbs the wait for the slowest rank, so that the gradients' all-reduce
  // after it measures the transfer alone.
  Clock::time_point in_step;
  s.exchange("the gradient all-reduce of step " + std::to_string(step + 1), [&] {
    std::vector<at::Tensor> others{side}, gradients{flat};
    s.group->allreduce(others)->wait();
    in_step = Clock::now();
    s.group->allreduce(gradients)->wait();
  });
  s.allreduce_seconds += std::chrono::duration<double>(Clock::now() - in_step).count();
  s.gradient_bytes = flat.numel() * static_cast<int64_t>(sizeof(float));
  const double n = static_cast<double>(s.options.world_size);
  flat.div_(n);
  for (size_t i = 0; i < values.size(); ++i) values[i] = side_data[i] / n;
  int64_t offset = 0;
  for (size_t i = 0; i < parameters.size(); ++i) {
    at::Tensor p = parameters[i];
    const int64_t count = p.numel();
    if (side_data[values.size() + i] > 0) {
      at::Tensor& grad = p.mutable_grad();
      if (!grad.defined()) grad = at::zeros_like(p);
      grad.detach().copy_(flat.narrow(0, offset, count).view(p.sizes()));
    }
    offset += count;
  }
  s.communication_seconds += std::chrono::duration<double>(Clock::now() - start).count();
  ++s.communication_count;
}

void DataParallelGroup::barrier(const std::string& what) {
  State& s = *state_;
  s.exchange("waiting for " + what, [&] { s.group->barrier()->wait(); });
}

double DataParallelGroup::communication_seconds() const { return state_->communication_seconds; }

double DataParallelGroup::allreduce_seconds() const { return state_->allreduce_seconds; }

int64_t DataParallelGroup::gradient_bytes() const { return state_->gradient_bytes; }

int64_t DataParallelGroup::communication_count() const { return state_->communication_count; }

}  // namespace amt
