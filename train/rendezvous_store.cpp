#include "train/rendezvous_store.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <poll.h>
#include <pwd.h>
#include <sys/random.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <map>
#include <mutex>
#include <sstream>
#include <thread>

#include "data_tools/formats/atomic_file.h"

namespace amt {
namespace {

using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

// The wire format: every message is a frame, its length as 4 bytes (big-endian) and then its bytes.
// A client's first frame is the hello (kMagic, then the token); the server answers kOk or kRefused with a
// message and then closes. After that, one request at a time: an operation byte and its fields, answered
// by a status byte and the result.
constexpr char kMagic[] = "amt-rendezvous-1";
constexpr size_t kMaxTokenLength = 256;
constexpr uint32_t kMaxHelloFrame = 4096;
// A rank's values are small (addresses, the run's settings); this only bounds a runaway client.
constexpr uint32_t kMaxFrame = 64u << 20;
// An unauthenticated connection holds a slot at most this long.
constexpr auto kHelloTime = std::chrono::seconds(10);

enum Op : uint8_t { kSet = 1, kGet, kAdd, kCompareSet, kCheck, kDelete, kNumKeys, kWait };
enum Status : uint8_t { kOk = 0, kTimedOut = 1, kRefused = 2 };

std::string seconds_text(milliseconds time) {
  std::ostringstream out;
  out << static_cast<double>(time.count()) / 1000.0 << " s";
  return out.str();
}

std::string random_hex(size_t bytes) {
  std::vector<unsigned char> data(bytes);
  size_t filled = 0;
  while (filled < bytes) {
    const ssize_t n = getrandom(data.data() + filled, bytes - filled, 0);
    if (n < 0 && errno == EINTR) continue;
    AMT_CHECK(n > 0, "cannot read the system's random source (", std::strerror(errno), ")");
    filled += static_cast<size_t>(n);
  }
  static const char digits[] = "0123456789abcdef";
  std::string text;
  for (unsigned char c : data) {
    text += digits[c >> 4];
    text += digits[c & 15];
  }
  return text;
}

// Equality of a presented token with the run's, in a time that does not depend on where they differ.
bool same_token(const std::string& presented, const std::string& expected) {
  unsigned char difference = presented.size() == expected.size() ? 0 : 1;
  for (size_t i = 0; i < kMaxTokenLength; ++i) {
    const unsigned char a = i < presented.size() ? static_cast<unsigned char>(presented[i]) : 0;
    const unsigned char b = i < expected.size() ? static_cast<unsigned char>(expected[i]) : 0;
    difference |= static_cast<unsigned char>(a ^ b);
  }
  return difference == 0;
}

struct Writer {
  std::string bytes;
  void u8(uint8_t v) { bytes.push_back(static_cast<char>(v)); }
  void u32(uint32_t v) {
    for (int i = 3; i >= 0; --i) bytes.push_back(static_cast<char>((v >> (8 * i)) & 0xff));
  }
  void u64(uint64_t v) {
    for (int i = 7; i >= 0; --i) bytes.push_back(static_cast<char>((v >> (8 * i)) & 0xff));
  }
  void blob(const void* data, size_t size) {
    u32(static_cast<uint32_t>(size));
    bytes.append(static_cast<const char*>(data), size);
  }
  void str(const std::string& s) { blob(s.data(), s.size()); }
  void vec(const std::vector<uint8_t>& v) { blob(v.data(), v.size()); }
  void keys(const std::vector<std::string>& keys) {
    u32(static_cast<uint32_t>(keys.size()));
    for (const std::string& k : keys) str(k);
  }
  std::string frame() const {
    Writer w;
    w.u32(static_cast<uint32_t>(bytes.size()));
    return w.bytes + bytes;
  }
};

struct Malformed {};

struct Reader {
  const std::string& bytes;
  size_t at = 0;
  void need(size_t n) const {
    if (bytes.size() - at < n) throw Malformed{};
  }
  uint8_t u8() {
    need(1);
    return static_cast<uint8_t>(bytes[at++]);
  }
  uint64_t number(int size) {
    need(static_cast<size_t>(size));
    uint64_t v = 0;
    for (int i = 0; i < size; ++i) v = (v << 8) | static_cast<unsigned char>(bytes[at++]);
    return v;
  }
  uint32_t u32() { return static_cast<uint32_t>(number(4)); }
  uint64_t u64() { return number(8); }
  std::string str() {
    const uint32_t size = u32();
    need(size);
    std::string s = bytes.substr(at, size);
    at += size;
    return s;
  }
  std::vector<uint8_t> vec() {
    const std::string s = str();
    return std::vector<uint8_t>(s.begin(), s.end());
  }
  std::vector<std::string> keys() {
    const uint32_t n = u32();
    std::vector<std::string> keys;
    for (uint32_t i = 0; i < n; ++i) keys.push_back(str());
    return keys;
  }
};

uint32_t frame_length(const std::string& buffer) {
  uint32_t n = 0;
  for (int i = 0; i < 4; ++i) n = (n << 8) | static_cast<unsigned char>(buffer[static_cast<size_t>(i)]);
  return n;
}

int remaining_ms(Clock::time_point deadline) {
  const auto left = std::chrono::duration_cast<milliseconds>(deadline - Clock::now()).count() + 1;
  return static_cast<int>(std::clamp<int64_t>(left, 0, 1000000));
}

enum class Io { kOk, kClosed, kTimedOut, kFailed };

// Sends all of `bytes` on the non-blocking socket by `deadline`.
Io send_all(int fd, const std::string& bytes, Clock::time_point deadline, int& error) {
  size_t sent = 0;
  while (sent < bytes.size()) {
    const ssize_t n = ::send(fd, bytes.data() + sent, bytes.size() - sent, MSG_NOSIGNAL);
    if (n > 0) {
      sent += static_cast<size_t>(n);
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK) {
      error = errno;
      return errno == EPIPE || errno == ECONNRESET ? Io::kClosed : Io::kFailed;
    }
    if (Clock::now() >= deadline) return Io::kTimedOut;
    pollfd p{fd, POLLOUT, 0};
    ::poll(&p, 1, remaining_ms(deadline));
  }
  return Io::kOk;
}

// Reads exactly `size` bytes from the non-blocking socket by `deadline`.
Io read_exact(int fd, char* data, size_t size, Clock::time_point deadline, int& error) {
  size_t got = 0;
  while (got < size) {
    const ssize_t n = ::recv(fd, data + got, size - got, 0);
    if (n > 0) {
      got += static_cast<size_t>(n);
      continue;
    }
    if (n == 0) return Io::kClosed;
    if (errno == EINTR) continue;
    if (errno != EAGAIN && errno != EWOULDBLOCK) {
      error = errno;
      return errno == ECONNRESET ? Io::kClosed : Io::kFailed;
    }
    if (Clock::now() >= deadline) return Io::kTimedOut;
    pollfd p{fd, POLLIN, 0};
    ::poll(&p, 1, remaining_ms(deadline));
  }
  return Io::kOk;
}

// Reads one frame's payload (at most `limit` bytes).
Io read_frame(int fd, std::string& payload, uint32_t limit, Clock::time_point deadline, int& error) {
  std::string head(4, '\0');
  Io io = read_exact(fd, head.data(), 4, deadline, error);
  if (io != Io::kOk) return io;
  const uint32_t size = frame_length(head);
  if (size > limit) {
    error = EMSGSIZE;
    return Io::kFailed;
  }
  payload.assign(size, '\0');
  return read_exact(fd, payload.data(), size, deadline, error);
}

std::string address_text(const sockaddr* address) {
  char text[INET6_ADDRSTRLEN] = "?";
  if (address->sa_family == AF_INET)
    inet_ntop(AF_INET, &reinterpret_cast<const sockaddr_in*>(address)->sin_addr, text, sizeof(text));
  else if (address->sa_family == AF_INET6)
    inet_ntop(AF_INET6, &reinterpret_cast<const sockaddr_in6*>(address)->sin6_addr, text, sizeof(text));
  return text;
}

// The addresses `host` resolves to for a TCP connection to `port`; empty with `error` set when none.
struct Addresses {
  addrinfo* list = nullptr;
  std::string error;
  Addresses(const std::string& host, int port) {
    addrinfo hints{};
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    hints.ai_flags = AI_NUMERICSERV;
    const int rc = getaddrinfo(host.c_str(), std::to_string(port).c_str(), &hints, &list);
    if (rc != 0) {
      error = std::string("cannot resolve ") + host + ": " + gai_strerror(rc);
      list = nullptr;
    }
  }
  ~Addresses() {
    if (list) freeaddrinfo(list);
  }
  Addresses(const Addresses&) = delete;
  Addresses& operator=(const Addresses&) = delete;
};

}  // namespace

// === Names, tokens

bool is_loopback_host(const std::string& host) {
  if (host == "localhost") return true;
  in_addr v4{};
  if (inet_pton(AF_INET, host.c_str(), &v4) == 1) return (ntohl(v4.s_addr) >> 24) == 127;
  in6_addr v6{};
  if (inet_pton(AF_INET6, host.c_str(), &v6) == 1) return IN6_IS_ADDR_LOOPBACK(&v6);
  return false;
}

void check_token(const std::string& token, const std::string& source) {
  bool printable = true;
  for (char c : token) printable = printable && c > ' ' && c < 127;
  AMT_CHECK(token.size() >= 16 && token.size() <= kMaxTokenLength && printable, source,
            ": expected a shared token of 16 to 256 printable characters without spaces (e.g. from `openssl rand "
            "-hex 32`), found ",
            token.size(), " characters", printable ? "" : " with spaces or control characters");
}

std::string generate_token() {
  return random_hex(32);
}

std::string local_token_path(const std::string& host, int port) {
  std::string home;
  if (const char* h = std::getenv("HOME"); h && *h) {
    home = h;
  } else if (const passwd* pw = getpwuid(geteuid()); pw && pw->pw_dir) {
    home = pw->pw_dir;
  }
  if (home.empty()) {
    throw RendezvousRefused(
        "--dist-token: no home folder to keep a local run's generated token in (HOME is unset); give every rank "
        "the same AMT_DIST_TOKEN");
  }
  std::string name;
  for (char c : host) name += std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '-' ? c : '_';
  return home + "/.cache/amt/rendezvous-" + name + "-" + std::to_string(port) + ".token";
}

void write_local_token(const std::string& path, const std::string& token) {
  namespace fs = std::filesystem;
  const fs::path folder = fs::path(path).parent_path();
  const auto refuse = [&](const std::string& why) {
    throw RendezvousRefused("--dist-token: cannot keep the generated token in " + path + " (" + why +
                            "); give every rank the same AMT_DIST_TOKEN");
  };
  std::error_code error;
  fs::create_directories(folder.parent_path(), error);
  if (::mkdir(folder.c_str(), 0700) != 0 && errno != EEXIST) refuse(std::strerror(errno));
  // The folder is this user's alone: anyone else who could write into it could swap the token file.
  struct stat st {};
  if (::lstat(folder.c_str(), &st) != 0) refuse(std::strerror(errno));
  if (!S_ISDIR(st.st_mode) || st.st_uid != geteuid() || (st.st_mode & 022) != 0)
    refuse(folder.string() + " is not a folder only this user writes");
  const std::string temporary = path + ".new-" + random_hex(8);
  const int fd = ::open(temporary.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0600);
  if (fd < 0) refuse(std::strerror(errno));
  const std::string text = token + "\n";
  const bool written = ::write(fd, text.data(), text.size()) == static_cast<ssize_t>(text.size());
  const int write_error = errno;
  ::close(fd);
  if (!written || ::rename(temporary.c_str(), path.c_str()) != 0) {
    const std::string why = std::strerror(written ? errno : write_error);
    ::unlink(temporary.c_str());
    refuse(why);
  }
}

std::string read_local_token(const std::string& path) {
  const auto refuse = [&](const std::string& why) {
    throw RendezvousRefused("--dist-token: cannot read the local run's token " + path + " (" + why +
                            "); rank 0 writes it when it starts: give every rank the same AMT_DIST_TOKEN when they do "
                            "not share this home folder and user");
  };
  const int fd = ::open(path.c_str(), O_RDONLY | O_NOFOLLOW | O_CLOEXEC);
  if (fd < 0) refuse(std::strerror(errno));
  struct stat st {};
  const bool owned = ::fstat(fd, &st) == 0 && S_ISREG(st.st_mode) && st.st_uid == geteuid() && (st.st_mode & 077) == 0;
  char buffer[1024];
  const ssize_t n = owned ? ::read(fd, buffer, sizeof(buffer)) : -1;
  ::close(fd);
  if (!owned) refuse("not a file of this user's that only it reads");
  if (n < 0) refuse(std::strerror(errno));
  std::string token(buffer, static_cast<size_t>(n));
  while (!token.empty() && (token.back() == '\n' || token.back() == '\r')) token.pop_back();
  check_token(token, path);
  return token;
}

// === Server

struct RendezvousStore::Server {
  struct Connection {
    int fd = -1;
    bool authenticated = false, closing = false, dead = false;
    Clock::time_point hello_deadline;
    std::string in, out;
    // A get or wait for keys not yet set, answered when they are or at the deadline.
    bool waiting = false;
    uint8_t wait_op = 0;
    std::vector<std::string> keys;
    Clock::time_point wait_deadline;
  };

  int listen_fd = -1;
  int wake[2] = {-1, -1};
  int port = 0;
  std::string token;
  size_t max_connections = 64;
  std::map<std::string, std::vector<uint8_t>> data;
  std::vector<std::unique_ptr<Connection>> connections;
  std::thread thread;

  explicit Server(const Options& o)
      : token(o.token), max_connections(static_cast<size_t>(std::max(2, o.max_connections))) {
    Addresses addresses(o.host, o.port);
    AMT_CHECK(addresses.list, addresses.error);
    std::string error = "no address";
    for (const addrinfo* a = addresses.list; a && listen_fd < 0; a = a->ai_next) {
      const int fd = ::socket(a->ai_family, a->ai_socktype | SOCK_CLOEXEC | SOCK_NONBLOCK, a->ai_protocol);
      if (fd < 0) {
        error = std::strerror(errno);
        continue;
      }
      int one = 1;
      // A rerun right after a killed one binds although the old connections linger in TIME_WAIT.
      ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof(one));
      if (a->ai_family == AF_INET6) ::setsockopt(fd, IPPROTO_IPV6, IPV6_V6ONLY, &one, sizeof(one));
      if (::bind(fd, a->ai_addr, a->ai_addrlen) == 0) {
        listen_fd = fd;
      } else {
        error = address_text(a->ai_addr) + ": " + std::strerror(errno);
        ::close(fd);
      }
    }
    AMT_CHECK(listen_fd >= 0, "cannot bind to ", o.host, ":", o.port, " (", error, ")");
    sockaddr_storage bound{};
    socklen_t size = sizeof(bound);
    ::getsockname(listen_fd, reinterpret_cast<sockaddr*>(&bound), &size);
    port = ntohs(bound.ss_family == AF_INET6 ? reinterpret_cast<sockaddr_in6*>(&bound)->sin6_port
                                             : reinterpret_cast<sockaddr_in*>(&bound)->sin_port);
    try {
      if (o.bound) o.bound(port);
      AMT_CHECK(::listen(listen_fd, 128) == 0, "cannot listen on ", o.host, ":", port, " (", std::strerror(errno), ")");
      AMT_CHECK(::pipe2(wake, O_CLOEXEC | O_NONBLOCK) == 0, "cannot create a pipe (", std::strerror(errno), ")");
    } catch (...) {
      ::close(listen_fd);
      throw;
    }
    thread = std::thread([this] { loop(); });
  }

  ~Server() {
    const char stop = 's';
    while (::write(wake[1], &stop, 1) < 0 && errno == EINTR) {
    }
    thread.join();
    for (auto& c : connections) ::close(c->fd);
    ::close(listen_fd);
    ::close(wake[0]);
    ::close(wake[1]);
  }

  void loop() {
    for (;;) {
      std::vector<pollfd> fds;
      fds.push_back({wake[0], POLLIN, 0});
      // A full house: newcomers wait in the listen queue until a slot frees.
      fds.push_back({connections.size() < max_connections ? listen_fd : -1, POLLIN, 0});
      const size_t polled = connections.size();
      Clock::time_point next = Clock::now() + std::chrono::seconds(1);
      for (const auto& c : connections) {
        short events = c->closing ? 0 : POLLIN;
        if (!c->out.empty()) events |= POLLOUT;
        fds.push_back({c->fd, events, 0});
        if (!c->authenticated) next = std::min(next, c->hello_deadline);
        if (c->waiting) next = std::min(next, c->wait_deadline);
      }
      if (::poll(fds.data(), fds.size(), remaining_ms(next)) < 0 && errno != EINTR) return;
      if (fds[0].revents != 0) return;
      if (fds[1].revents & POLLIN) accept_new();
      for (size_t i = 0; i < polled; ++i) {
        Connection& c = *connections[i];
        const short events = fds[2 + i].revents;
        if (events & POLLOUT) flush(c);
        if (events & (POLLIN | POLLHUP | POLLERR)) receive(c);
      }
      const auto now = Clock::now();
      for (auto& c : connections) {
        if (!c->authenticated && now >= c->hello_deadline) c->dead = true;
        if (c->waiting && now >= c->wait_deadline) {
          c->waiting = false;
          Writer w;
          w.u8(kTimedOut);
          reply(*c, w);
          process(*c);
        }
        if (c->closing && c->out.empty()) c->dead = true;
      }
      for (auto it = connections.begin(); it != connections.end();) {
        if ((*it)->dead) {
          ::close((*it)->fd);
          it = connections.erase(it);
        } else {
          ++it;
        }
      }
    }
  }

  void accept_new() {
    while (connections.size() < max_connections) {
      const int fd = ::accept4(listen_fd, nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK);
      if (fd < 0) return;
      auto c = std::make_unique<Connection>();
      c->fd = fd;
      c->hello_deadline = Clock::now() + kHelloTime;
      connections.push_back(std::move(c));
    }
  }

  void flush(Connection& c) {
    while (!c.out.empty()) {
      const ssize_t n = ::send(c.fd, c.out.data(), c.out.size(), MSG_NOSIGNAL);
      if (n > 0) {
        c.out.erase(0, static_cast<size_t>(n));
      } else if (n < 0 && errno == EINTR) {
        continue;
      } else {
        if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK) c.dead = true;
        return;
      }
    }
  }

  void receive(Connection& c) {
    char buffer[65536];
    for (;;) {
      const ssize_t n = ::recv(c.fd, buffer, sizeof(buffer), 0);
      if (n > 0) {
        if (!c.closing) c.in.append(buffer, static_cast<size_t>(n));
        // A stranger gets no more than one hello's worth of memory.
        if (!c.authenticated && c.in.size() > kMaxHelloFrame + 4) {
          c.dead = true;
          return;
        }
        continue;
      }
      if (n < 0 && errno == EINTR) continue;
      if (n == 0 || (errno != EAGAIN && errno != EWOULDBLOCK)) c.dead = true;
      break;
    }
    process(c);
  }

  void reply(Connection& c, const Writer& w) {
    c.out += w.frame();
    flush(c);
  }

  void refuse(Connection& c, const std::string& message) {
    Writer w;
    w.u8(kRefused);
    w.str(message);
    reply(c, w);
    c.closing = true;
    c.in.clear();
  }

  // Handles the complete frames received, one request at a time.
  void process(Connection& c) {
    while (!c.dead && !c.closing && !c.waiting && c.in.size() >= 4) {
      const uint32_t size = frame_length(c.in);
      if (size > (c.authenticated ? kMaxFrame : kMaxHelloFrame)) {
        refuse(c, "amt rendezvous: message too large");
        return;
      }
      if (c.in.size() < 4 + static_cast<size_t>(size)) return;
      const std::string payload = c.in.substr(4, size);
      c.in.erase(0, 4 + static_cast<size_t>(size));
      try {
        handle(c, payload);
      } catch (const Malformed&) {
        refuse(c, "amt rendezvous: malformed request");
      }
    }
  }

  bool has_all(const std::vector<std::string>& keys) const {
    return std::all_of(keys.begin(), keys.end(), [&](const std::string& k) { return data.count(k) > 0; });
  }

  void handle(Connection& c, const std::string& payload) {
    Reader r{payload};
    if (!c.authenticated) {
      if (r.str() != kMagic) {
        refuse(c, "this port is an amt rendezvous; the client did not introduce itself as an amt rank");
        return;
      }
      if (!same_token(r.str(), token)) {
        refuse(c,
               "the rendezvous refused this rank's token: every rank must present the same --dist-token or "
               "AMT_DIST_TOKEN");
        return;
      }
      c.authenticated = true;
      Writer w;
      w.u8(kOk);
      reply(c, w);
      return;
    }
    Writer w;
    w.u8(kOk);
    bool changed = false;
    const uint8_t op = r.u8();
    switch (op) {
      case kSet: {
        const std::string key = r.str();
        data[key] = r.vec();
        changed = true;
        break;
      }
      case kGet:
      case kWait: {
        c.keys = op == kGet ? std::vector<std::string>{r.str()} : r.keys();
        const uint64_t ms = r.u64();
        if (!has_all(c.keys)) {
          c.waiting = true;
          c.wait_op = op;
          c.wait_deadline = Clock::now() + milliseconds(static_cast<int64_t>(std::min<uint64_t>(ms, 1ull << 40)));
          return;
        }
        if (op == kGet) w.vec(data[c.keys[0]]);
        break;
      }
      case kAdd: {
        const std::string key = r.str();
        const int64_t delta = static_cast<int64_t>(r.u64());
        int64_t value = 0;
        if (const auto it = data.find(key); it != data.end()) {
          const std::string text(it->second.begin(), it->second.end());
          try {
            value = std::stoll(text);
          } catch (const std::exception&) {
            refuse(c, "amt rendezvous: add to key '" + key + "', which holds no number");
            return;
          }
        }
        value += delta;
        const std::string text = std::to_string(value);
        data[key] = std::vector<uint8_t>(text.begin(), text.end());
        w.u64(static_cast<uint64_t>(value));
        changed = true;
        break;
      }
      case kCompareSet: {
        // As c10d's TCPStore: set `desired` when the key holds `expected` (or is absent and `expected`
        // empty); answer the value the key then holds (`expected` for an absent key otherwise).
        const std::string key = r.str();
        const std::vector<uint8_t> expected = r.vec(), desired = r.vec();
        const auto it = data.find(key);
        if (it == data.end()) {
          if (expected.empty()) {
            data[key] = desired;
            changed = true;
            w.vec(desired);
          } else {
            w.vec(expected);
          }
        } else {
          if (it->second == expected) {
            it->second = desired;
            changed = true;
          }
          w.vec(it->second);
        }
        break;
      }
      case kCheck:
        w.u8(has_all(r.keys()) ? 1 : 0);
        break;
      case kDelete:
        w.u8(data.erase(r.str()) > 0 ? 1 : 0);
        break;
      case kNumKeys:
        w.u64(data.size());
        break;
      default:
        refuse(c, "amt rendezvous: unknown request " + std::to_string(op));
        return;
    }
    reply(c, w);
    if (changed) answer_waiters();
  }

  void answer_waiters() {
    for (auto& other : connections) {
      Connection& c = *other;
      if (!c.waiting || !has_all(c.keys)) continue;
      c.waiting = false;
      Writer w;
      w.u8(kOk);
      if (c.wait_op == kGet) w.vec(data[c.keys[0]]);
      reply(c, w);
      process(c);
    }
  }
};

// === Client

struct RendezvousStore::Client {
  std::string host;
  int port = 0;
  int fd = -1;
  std::mutex mutex;
  std::string broken;  // why the connection is unusable ("" while it is)

  std::string where() const { return "rendezvous " + host + ":" + std::to_string(port); }

  ~Client() {
    if (fd >= 0) ::close(fd);
  }

  // A connected socket to the server, or -1 with `error` set.
  int connect_once(std::string& error, Clock::time_point deadline) {
    Addresses addresses(host, port);
    if (!addresses.list) {
      error = addresses.error;
      return -1;
    }
    for (const addrinfo* a = addresses.list; a; a = a->ai_next) {
      const int s = ::socket(a->ai_family, a->ai_socktype | SOCK_CLOEXEC | SOCK_NONBLOCK, a->ai_protocol);
      if (s < 0) {
        error = std::strerror(errno);
        continue;
      }
      int result = ::connect(s, a->ai_addr, a->ai_addrlen) == 0 ? 0 : errno;
      if (result == EINPROGRESS) {
        pollfd p{s, POLLOUT, 0};
        const int waited = ::poll(&p, 1, std::min(remaining_ms(deadline), 2000));
        socklen_t size = sizeof(result);
        if (waited <= 0) {
          result = ETIMEDOUT;
        } else if (::getsockopt(s, SOL_SOCKET, SO_ERROR, &result, &size) != 0) {
          result = errno;
        }
      }
      if (result == 0) return s;
      error = address_text(a->ai_addr) + ": " + std::strerror(result);
      ::close(s);
    }
    return -1;
  }

  // Connects (retrying until rank 0 listens or the timeout ends) and presents the token.
  void join(const Options& o, milliseconds timeout) {
    const auto deadline = Clock::now() + timeout;
    std::string error = "no answer";
    for (;;) {
      fd = connect_once(error, deadline);
      if (fd >= 0) {
        Writer hello;
        hello.str(kMagic);
        hello.str(o.token.empty() && o.read_token ? o.read_token() : o.token);
        int code = 0;
        std::string answer;
        const auto answer_by = std::max(deadline, Clock::now() + std::chrono::seconds(1));
        Io io = send_all(fd, hello.frame(), answer_by, code);
        if (io == Io::kOk) io = read_frame(fd, answer, kMaxHelloFrame, answer_by, code);
        if (io == Io::kOk) {
          Reader r{answer};
          uint8_t status = kRefused;
          std::string message;
          try {
            status = r.u8();
            if (status != kOk) message = r.str();
          } catch (const Malformed&) {
            message = "it answered in a form amt does not know";
          }
          if (status == kOk) return;
          throw RendezvousRefused(where() + ": " + message);
        }
        // Closed before answering: a server with no slot free, or one still starting; try again.
        error = io == Io::kTimedOut ? "no answer to the hello" : "the connection closed before the hello's answer";
        ::close(fd);
        fd = -1;
      }
      if (Clock::now() >= deadline) fail(where(), ": not reached within ", seconds_text(timeout), " (", error, ")");
      std::this_thread::sleep_for(std::min<Clock::duration>(milliseconds(100), deadline - Clock::now()));
    }
  }

  // Sends a request and returns the answer after its status byte. `wait`: how long the server may
  // hold the answer back (a get or wait); the answer is due by then plus `grace`.
  std::string request(const Writer& w, const std::string& what, milliseconds wait, milliseconds grace) {
    std::lock_guard<std::mutex> lock(mutex);
    AMT_CHECK(broken.empty(), where(), ": ", what, ": the connection was lost earlier (", broken, ")");
    const auto deadline = Clock::now() + wait + grace;
    int code = 0;
    std::string answer;
    Io io = send_all(fd, w.frame(), deadline, code);
    if (io == Io::kOk) io = read_frame(fd, answer, kMaxFrame + 8, deadline, code);
    if (io != Io::kOk) {
      broken = io == Io::kClosed     ? "rank 0's rendezvous closed the connection: rank 0 stopped"
               : io == Io::kTimedOut ? "no answer within " + seconds_text(wait + grace)
                                     : std::string(std::strerror(code));
      fail(where(), ": ", what, ": ", broken);
    }
    Reader r{answer};
    try {
      const uint8_t status = r.u8();
      if (status == kTimedOut) fail(where(), ": ", what, ": not set within ", seconds_text(wait));
      if (status == kRefused) {
        broken = r.str();
        throw RendezvousRefused(where() + ": " + broken);
      }
    } catch (const Malformed&) {
      broken = "a malformed answer";
      fail(where(), ": ", what, ": ", broken);
    }
    return answer.substr(1);
  }
};

RendezvousStore::RendezvousStore(Options options) : c10d::Store(options.timeout) {
  int port = options.port;
  if (options.serve) {
    server_ = std::make_unique<Server>(options);
    port = server_->port;
  }
  client_ = std::make_unique<Client>();
  client_->host = options.host;
  client_->port = port;
  client_->join(options, options.timeout);
}

RendezvousStore::~RendezvousStore() {
  client_.reset();
  server_.reset();
}

int RendezvousStore::port() const {
  return client_->port;
}

namespace {
// The keys' names for messages: "key 'a'" or "keys 'a', 'b'".
std::string keys_text(const std::vector<std::string>& keys) {
  std::string text = keys.size() == 1 ? "key " : "keys ";
  for (size_t i = 0; i < keys.size(); ++i) text += (i ? ", '" : "'") + keys[i] + "'";
  return text;
}
}  // namespace

void RendezvousStore::set(const std::string& key, const std::vector<uint8_t>& value) {
  Writer w;
  w.u8(kSet);
  w.str(key);
  w.vec(value);
  client_->request(w, "setting key '" + key + "'", milliseconds(0), timeout_);
}

std::vector<uint8_t> RendezvousStore::compareSet(const std::string& key, const std::vector<uint8_t>& expected,
                                                 const std::vector<uint8_t>& desired) {
  Writer w;
  w.u8(kCompareSet);
  w.str(key);
  w.vec(expected);
  w.vec(desired);
  const std::string answer = client_->request(w, "compare-and-set of key '" + key + "'", milliseconds(0), timeout_);
  Reader r{answer};
  try {
    return r.vec();
  } catch (const Malformed&) {
    fail(client_->where(), ": compare-and-set of key '", key, "': a malformed answer");
  }
}

std::vector<uint8_t> RendezvousStore::get(const std::string& key) {
  Writer w;
  w.u8(kGet);
  w.str(key);
  w.u64(static_cast<uint64_t>(timeout_.count()));
  const std::string answer =
      client_->request(w, keys_text({key}), timeout_, std::min<milliseconds>(timeout_, std::chrono::seconds(10)));
  Reader r{answer};
  try {
    return r.vec();
  } catch (const Malformed&) {
    fail(client_->where(), ": ", keys_text({key}), ": a malformed answer");
  }
}

int64_t RendezvousStore::add(const std::string& key, int64_t value) {
  Writer w;
  w.u8(kAdd);
  w.str(key);
  w.u64(static_cast<uint64_t>(value));
  const std::string answer = client_->request(w, "adding to key '" + key + "'", milliseconds(0), timeout_);
  Reader r{answer};
  try {
    return static_cast<int64_t>(r.u64());
  } catch (const Malformed&) {
    fail(client_->where(), ": adding to key '", key, "': a malformed answer");
  }
}

bool RendezvousStore::deleteKey(const std::string& key) {
  Writer w;
  w.u8(kDelete);
  w.str(key);
  const std::string answer = client_->request(w, "deleting key '" + key + "'", milliseconds(0), timeout_);
  return !answer.empty() && answer[0] == 1;
}

bool RendezvousStore::check(const std::vector<std::string>& keys) {
  Writer w;
  w.u8(kCheck);
  w.keys(keys);
  const std::string answer = client_->request(w, "checking " + keys_text(keys), milliseconds(0), timeout_);
  return !answer.empty() && answer[0] == 1;
}

int64_t RendezvousStore::getNumKeys() {
  Writer w;
  w.u8(kNumKeys);
  const std::string answer = client_->request(w, "counting the keys", milliseconds(0), timeout_);
  Reader r{answer};
  try {
    return static_cast<int64_t>(r.u64());
  } catch (const Malformed&) {
    fail(client_->where(), ": counting the keys: a malformed answer");
  }
}

void RendezvousStore::wait(const std::vector<std::string>& keys) {
  wait(keys, timeout_);
}

void RendezvousStore::wait(const std::vector<std::string>& keys, const milliseconds& timeout) {
  const milliseconds bound = timeout.count() > 0 ? timeout : timeout_;
  Writer w;
  w.u8(kWait);
  w.keys(keys);
  w.u64(static_cast<uint64_t>(bound.count()));
  client_->request(w, keys_text(keys), bound, std::min<milliseconds>(timeout_, std::chrono::seconds(10)));
}

// === File rendezvous

const char* FileRendezvous::header() {
  return "amt data-parallel rendezvous 1";
}

namespace {

enum class Marker { kAmt, kPartial, kForeign };

// What the first bytes of a file at a rendezvous path say: amt's marker (its run id in `run_id`), the start
// of one, or something else.
Marker parse_marker(const std::string& text, std::string& run_id) {
  const std::string head = std::string(FileRendezvous::header()) + "\n";
  if (text.size() < head.size()) return head.compare(0, text.size(), text) == 0 ? Marker::kPartial : Marker::kForeign;
  if (text.compare(0, head.size(), head) != 0) return Marker::kForeign;
  const std::string rest = text.substr(head.size());
  if (rest.size() < 37 || rest.compare(0, 4, "run ") != 0 || rest[36] != '\n') return Marker::kPartial;
  const std::string id = rest.substr(4, 32);
  if (!std::all_of(id.begin(), id.end(), [](char c) { return std::isxdigit(static_cast<unsigned char>(c)); }))
    return Marker::kPartial;
  run_id = id;
  return Marker::kAmt;
}

std::string read_head(int fd) {
  char buffer[4096];
  std::string text;
  for (;;) {
    const ssize_t n = ::read(fd, buffer, sizeof(buffer) - text.size());
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    text.append(buffer, static_cast<size_t>(n));
    if (text.size() >= sizeof(buffer) - 1) break;
  }
  return text;
}

// Whether a process holds a lock on the open file (a live rank 0); `unknown` when the file system
// cannot tell.
bool locked_by_a_run(int fd, bool& unknown) {
  struct flock lock {};
  lock.l_type = F_WRLCK;
  lock.l_whence = SEEK_SET;
  if (::fcntl(fd, F_OFD_GETLK, &lock) != 0) {
    unknown = true;
    return false;
  }
  return lock.l_type != F_UNLCK;
}

std::string not_amts(const std::string& path, const std::string& what) {
  return "--rendezvous: " + path + " is " + what + ", not a rendezvous amt made (its first line would be '" +
         FileRendezvous::header() + "'); amt leaves it as it is: give a path that does not exist";
}

}  // namespace

FileRendezvous::FileRendezvous(const std::string& path, bool first, milliseconds timeout) : path_(path) {
  namespace fs = std::filesystem;
  const auto deadline = Clock::now() + timeout;
  // What is at the path now: nothing, amt's marker of a live or a stale run, or something else.
  const auto look = [&](std::string& run_id, bool& live) -> bool {
    struct stat st {};
    if (::lstat(path.c_str(), &st) != 0) return false;
    std::error_code ignored;
    if (!S_ISREG(st.st_mode)) fail(not_amts(path, describe_file_type(fs::symlink_status(path, ignored).type())));
    const int fd = ::open(path.c_str(), O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) {
      if (errno == ENOENT) return false;
      fail("--rendezvous: cannot read ", path, " (", std::strerror(errno), ")");
    }
    const Marker marker = parse_marker(read_head(fd), run_id);
    bool unknown = false;
    live = marker == Marker::kAmt && locked_by_a_run(fd, unknown);
    // A file system without locks cannot tell; the marker is taken as current (rank 0 refuses to start
    // a run on such a file system, so this marker is a run's).
    if (unknown && !first) live = true;
    ::close(fd);
    if (marker == Marker::kForeign) fail(not_amts(path, "a file amt did not write"));
    return true;
  };

  if (!first) {
    std::string state = "it does not exist yet";
    for (;;) {
      std::string run_id;
      bool live = false;
      if (look(run_id, live)) {
        if (live) {
          run_id_ = run_id;
          store_path_ = path + ".run-" + run_id;
          return;
        }
        state = run_id.empty() ? "it is being written"
                               : "it names the run " + run_id +
                                     " of an earlier run whose rank 0 is gone (the next "
                                     "rank 0 replaces it)";
      }
      if (Clock::now() >= deadline) {
        fail("--rendezvous: no run started at ", path, " within ", seconds_text(timeout), " (--dist-timeout): ", state,
             "; start rank 0 with the same --rendezvous");
      }
      std::this_thread::sleep_for(std::min<Clock::duration>(milliseconds(50), deadline - Clock::now()));
    }
  }

  std::string old_run;
  bool live = false;
  if (look(old_run, live)) {
    AMT_CHECK(!live, "--rendezvous: ", path, " is in use by the run ", old_run,
              ", whose rank 0 is alive; stop that run or give this one another path");
  }
  run_id_ = random_hex(16);
  store_path_ = path + ".run-" + run_id_;
  // The run's store is new and empty; the marker naming it is written under another name and locked
  // before it replaces the old one, so that no rank ever sees it unlocked.
  const int store = ::open(store_path_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0600);
  AMT_CHECK(store >= 0, "--rendezvous: cannot create the run's store ", store_path_, " (", std::strerror(errno), ")");
  ::close(store);
  const std::string temporary = store_path_ + ".marker";
  const auto give_up = [&](const std::string& why) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
    ::unlink(temporary.c_str());
    ::unlink(store_path_.c_str());
    fail("--rendezvous: ", path, ": ", why);
  };
  fd_ = ::open(temporary.c_str(), O_RDWR | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0600);
  if (fd_ < 0) give_up(std::string("cannot create ") + temporary + " (" + std::strerror(errno) + ")");
  struct flock lock {};
  lock.l_type = F_WRLCK;
  lock.l_whence = SEEK_SET;
  if (::fcntl(fd_, F_OFD_SETLK, &lock) != 0) {
    give_up(std::string("cannot lock the marker (") + std::strerror(errno) +
            "); a file:// rendezvous needs a file system with file locks, to tell a live run from a stale one: use "
            "another folder or a tcp:// rendezvous");
  }
  const std::string text = std::string(header()) + "\nrun " + run_id_ + "\n";
  if (::write(fd_, text.data(), text.size()) != static_cast<ssize_t>(text.size()))
    give_up(std::string("cannot write the marker (") + std::strerror(errno) + ")");
  if (::rename(temporary.c_str(), path.c_str()) != 0)
    give_up(std::string("cannot replace the marker (") + std::strerror(errno) + ")");
  // The stores of earlier runs beside it: a live run would have held the marker, so nobody uses them.
  const fs::path folder = fs::absolute(path).parent_path();
  const std::string prefix = fs::path(path).filename().string() + ".run-";
  std::error_code error;
  for (const auto& entry : fs::directory_iterator(folder, error)) {
    const std::string name = entry.path().filename().string();
    if (name.compare(0, prefix.size(), prefix) != 0) continue;
    std::string rest = name.substr(prefix.size());
    if (rest.size() == 32 + 7 && rest.compare(32, 7, ".marker") == 0) rest.resize(32);
    if (rest.size() != 32 || rest == run_id_ ||
        !std::all_of(rest.begin(), rest.end(), [](char c) { return std::isxdigit(static_cast<unsigned char>(c)); }))
      continue;
    std::error_code ignored;
    if (entry.symlink_status(ignored).type() == fs::file_type::regular) fs::remove(entry.path(), ignored);
  }
}

FileRendezvous::~FileRendezvous() {
  if (fd_ < 0) return;
  // Removed only while the path is still this run's marker.
  struct stat mine {
  }, there{};
  if (::fstat(fd_, &mine) == 0 && ::lstat(path_.c_str(), &there) == 0 && mine.st_dev == there.st_dev &&
      mine.st_ino == there.st_ino) {
    ::unlink(path_.c_str());
  }
  ::close(fd_);
}

}  // namespace amt
