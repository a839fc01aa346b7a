#pragma once
// Data-parallel training across processes (issue 15) on PyTorch's distributed package as Debian's
// LibTorch ships it: the ranks meet at a rendezvous (amt's own store for tcp://, which listens on the
// named address only and wants the run's token, or a c10d::FileStore behind amt's marker for file://;
// train/rendezvous_store.h), form a c10d::ProcessGroupGloo, start from rank 0's parameters and average
// their gradients every step.
// This header stays free of c10d and Gloo (train/distributed.cpp holds them) so that the trainer
// and the command line compile without them.
#include <ATen/core/Tensor.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace amt {

// === Options

/// Where the ranks of a data-parallel run meet and how long they wait for one another.
struct DistributedOptions {
  /// Number of processes (ranks) of the run, and this process's rank in [0, world_size). 1: a run of
  /// its own, without a process group.
  int world_size = 1;
  int rank = 0;
  /// "tcp://HOST:PORT" (rank 0 listens on PORT of HOST's address only; HOST is rank 0's address as the
  /// others reach it) or "file://PATH" (on a file system every rank sees: nothing there, or the marker of an
  /// earlier amt run, which rank 0 replaces; the run's store is PATH.run-<id> beside it; both are removed
  /// when the run ends). Empty for world_size 1.
  std::string rendezvous;
  /// Seconds a rank waits for all ranks to join, and for the others in any one exchange (gradients,
  /// parameters), before it stops with an error. Validation and checkpoints of rank 0 happen while
  /// the others wait, so they must fit in it.
  double timeout_seconds = 300.0;
  /// The shared token every rank presents to a tcp:// rendezvous (--dist-token or AMT_DIST_TOKEN). Empty:
  /// allowed on a loopback address only, where rank 0 generates one for the local ranks
  /// (train/rendezvous_store.h, local_token_path).
  std::string token;
};

/// A parsed rendezvous URL.
struct Rendezvous {
  /// "tcp" or "file".
  std::string scheme;
  /// tcp: host name or address and port (1 .. 65535).
  std::string host;
  int port = 0;
  /// file: the store file's path.
  std::string path;
};

/// Parses "tcp://HOST:PORT" or "file://PATH". Throws amt::Error "--rendezvous: expected tcp://HOST:PORT or
/// file://PATH, found '...'" otherwise.
Rendezvous parse_rendezvous(const std::string& url);

/// Completes the command-line values `given` (world_size <= 0, rank < 0, empty rendezvous: not given) from
/// the environment variables torchrun and cluster schedulers set: WORLD_SIZE, RANK, and MASTER_ADDR with
/// MASTER_PORT (the rendezvous tcp://MASTER_ADDR:MASTER_PORT); the command line wins. `getenv` looks a
/// variable up (nullptr when unset). Throws amt::Error naming the option or variable for a malformed or
/// inconsistent value: world size < 1, a rank outside [0, world size), no rendezvous for world size > 1,
/// a malformed rendezvous, a timeout <= 0. The token comes from AMT_DIST_TOKEN when not given; a malformed
/// one, or none for a tcp:// rendezvous on an address other than loopback, is refused.
DistributedOptions resolve_distributed_options(DistributedOptions given,
                                               const std::function<const char*(const char*)>& getenv);

// === Process group

/// This process's membership of a data-parallel run: joined in the constructor, left in the destructor.
/// Every rank must make the same calls in the same order (they are collective).
class DataParallelGroup {
 public:
  /// Joins the run: connects to the rendezvous (rank 0 of a tcp:// rendezvous listens on its port; rank 0
  /// of a file:// one starts a new run there), then every rank to every other over Gloo's TCP transport.
  /// Throws amt::Error naming the rendezvous, the ranks that did not join and --dist-timeout when the others
  /// are not all there within the timeout, and naming the option when the rendezvous refuses this rank (a
  /// wrong token, a file amt did not make).
  explicit DataParallelGroup(const DistributedOptions& options);
  ~DataParallelGroup();
  DataParallelGroup(const DataParallelGroup&) = delete;
  DataParallelGroup& operator=(const DataParallelGroup&) = delete;

  int rank() const;
  int world_size() const;

  /// Checks that every rank gives the same `text` for `what` (the run's settings, the data's fingerprint):
  /// rank 0 publishes its text, the others compare. Throws amt::Error on a rank whose text differs,
  /// naming `what` and both texts; rank 0 then stops at the next exchange.
  void expect_same(const std::string& what, const std::string& text);

  /// Copies rank 0's values of `tensors` (parameters and buffers, any shapes and dtypes) into every rank's.
  void broadcast_from_rank0(const std::vector<at::Tensor>& tensors);

  /// After each rank's backward pass of step `step` (0-based): sets the gradient of each of `parameters`
  /// to the mean over ranks of their gradients (an undefined gradient counts as zeros; it stays undefined
  /// where no rank has one), and replaces each of `values` (the rank's loss terms) by their mean over
  /// ranks. Two all-reduces, one after the other: the values and gradient flags as doubles (where the
  /// ranks wait for the slowest), then the gradients as one float buffer.
  void average_gradients(const std::vector<at::Tensor>& parameters, std::vector<double>& values, int64_t step);

  /// Waits until every rank has called it (`what` names what the ranks wait for, in the error message).
  void barrier(const std::string& what);

  /// Seconds spent in the exchanges of average_gradients so far (including the wait for slower ranks), and
  /// how many it made.
  double communication_seconds() const;
  int64_t communication_count() const;
  /// Seconds of those spent in the gradients' all-reduce alone, which starts when the ranks are in step.
  double allreduce_seconds() const;
  /// Bytes of the last gradient all-reduce's buffer (4 per parameter).
  int64_t gradient_bytes() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace amt
