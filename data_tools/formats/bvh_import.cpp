// BVH import. The parser is hand-written: no Debian package provides a BVH parser that returns the file
// as written (libassimp-dev imports BVH into its own scene graph and key frames, dropping the channel
// orders and the frame layout, and would be a large dependency for one small text format).
#include "data_tools/formats/bvh_import.h"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <unordered_map>
#include <unordered_set>

#include "data_tools/geometry/error.h"
#include "data_tools/formats/input_file.h"

namespace amt {

namespace {

// Bounds on what a file may declare, far above any real file.
constexpr int kMaxJoints = 100000;
constexpr int kMaxChannelsPerJoint = 6;
constexpr double kMinFrameTime = 1e-6;    // seconds
constexpr double kMaxFrameTime = 10.0;    // seconds
constexpr double kMaxMagnitude = 1e9;     // of any number: a kilometre in millimetres, or 1e9 degrees
constexpr double kMaxScale = 1000.0;      // metres per file unit, so positions stay far inside float range
constexpr double kMaxJointFrames = 1e8;   // frames x joints of a converted motion (1.6 GB of rotations)
constexpr double kDegrees = M_PI / 180.0;

bool is_blank(char c) {
  return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}
bool is_space(char c) {
  return is_blank(c) || c == '\n';
}

bool iequals(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i) {
    const char x = a[i] >= 'A' && a[i] <= 'Z' ? static_cast<char>(a[i] - 'A' + 'a') : a[i];
    const char y = b[i] >= 'A' && b[i] <= 'Z' ? static_cast<char>(b[i] - 'A' + 'a') : b[i];
    if (x != y) return false;
  }
  return true;
}

// A token as it appears in a one-line message: quoted, control bytes escaped, long ones cut.
std::string quoted(std::string_view token) {
  if (token.empty()) return "end of file";
  constexpr size_t kLimit = 40;
  std::string out = "'";
  for (size_t i = 0; i < token.size() && i < kLimit; ++i) {
    const unsigned char c = static_cast<unsigned char>(token[i]);
    if (c < 0x20 || c == 0x7F) {
      char hex[8];
      std::snprintf(hex, sizeof hex, "\\x%02X", c);
      out += hex;
    } else {
      out += static_cast<char>(c);
    }
  }
  out += token.size() > kLimit ? "...'" : "'";
  return out;
}

// A decimal number of magnitude at most kMaxMagnitude, the whole token ("+1.5", ".0083333", "-0.0000",
// "1e-3"); not NaN or infinite.
bool parse_number(std::string_view token, double& out) {
  if (!token.empty() && token[0] == '+') {
    token.remove_prefix(1);
    if (!token.empty() && token[0] == '-') return false;
  }
  if (token.empty()) return false;
  const char* end = token.data() + token.size();
  const auto [ptr, ec] = std::from_chars(token.data(), end, out, std::chars_format::general);
  return ec == std::errc() && ptr == end && std::abs(out) <= kMaxMagnitude;
}

// A whole number, the whole token.
bool parse_integer(std::string_view token, long long& out) {
  if (!token.empty() && token[0] == '+') token.remove_prefix(1);
  if (token.empty()) return false;
  const char* end = token.data() + token.size();
  const auto [ptr, ec] = std::from_chars(token.data(), end, out);
  return ec == std::errc() && ptr == end;
}

bool channel_from_name(std::string_view name, BvhChannel& out) {
  static const BvhChannel all[] = {BvhChannel::kXposition, BvhChannel::kYposition, BvhChannel::kZposition,
                                   BvhChannel::kXrotation, BvhChannel::kYrotation, BvhChannel::kZrotation};
  for (BvhChannel channel : all) {
    if (iequals(name, bvh_channel_name(channel))) {
      out = channel;
      return true;
    }
  }
  return false;
}

bool is_rotation(BvhChannel c) {
  return c >= BvhChannel::kXrotation;
}
int axis_of(BvhChannel c) {
  return static_cast<int>(c) % 3;
}

// Walks the text token by token, keeping the line number for messages.
class Cursor {
 public:
  Cursor(std::string_view text, const std::string& source) : text_(text), source_(source) {
    if (text_.substr(0, 3) == "\xEF\xBB\xBF") pos_ = 3;  // UTF-8 byte order mark
  }

  // The next whitespace-separated token; empty at the end of the text.
  std::string_view next() {
    skip_space();
    token_line_ = at_end() ? last_content_line() : line_;
    const size_t start = pos_;
    while (pos_ < text_.size() && !is_space(text_[pos_])) ++pos_;
    return text_.substr(start, pos_ - start);
  }

  // The next token without consuming it.
  std::string_view peek() {
    const size_t pos = pos_;
    const int line = line_, token_line = token_line_;
    const std::string_view token = next();
    pos_ = pos, line_ = line, token_line_ = token_line;
    return token;
  }

  // The rest of the current line, trimmed: a joint name, which may hold spaces ("Bip01 L Thigh"). An
  // opening brace at its end ("Hips {") is left to be read as the next token.
  std::string_view rest_of_line() {
    while (pos_ < text_.size() && is_blank(text_[pos_])) ++pos_;
    token_line_ = line_;
    const size_t start = pos_;
    while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
    size_t end = pos_;
    while (end > start && is_blank(text_[end - 1])) --end;
    if (end > start && text_[end - 1] == '{' && (end - 1 == start || is_blank(text_[end - 2]))) {
      pos_ = end - 1;
      --end;
      while (end > start && is_blank(text_[end - 1])) --end;
    }
    return text_.substr(start, end - start);
  }

  // Skips blanks up to the end of the line; returns what follows on the line (empty if nothing).
  std::string_view rest_of_line_raw() {
    while (pos_ < text_.size() && is_blank(text_[pos_])) ++pos_;
    token_line_ = line_;
    const size_t start = pos_;
    while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
    return text_.substr(start, pos_ - start);
  }

  // Moves past the next line break (or to the end); returns false at the end of the text.
  bool next_line() {
    while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
    if (pos_ == text_.size()) return false;
    ++pos_;
    ++line_;
    return true;
  }

  // The next token on the current line (empty at the end of the line); never crosses a line break.
  std::string_view next_on_line() {
    while (pos_ < text_.size() && is_blank(text_[pos_])) ++pos_;
    token_line_ = line_;
    const size_t start = pos_;
    while (pos_ < text_.size() && !is_space(text_[pos_])) ++pos_;
    return text_.substr(start, pos_ - start);
  }

  bool at_end_of_line() {
    while (pos_ < text_.size() && is_blank(text_[pos_])) ++pos_;
    return pos_ == text_.size() || text_[pos_] == '\n';
  }

  bool at_end() const { return pos_ >= text_.size(); }
  size_t remaining() const { return text_.size() - pos_; }
  int line() const { return token_line_; }

  // Throws "source:LINE: field: expected X, found Y" for the last token read.
  template <typename... Parts>
  [[noreturn]] void fail(const std::string& field, const Parts&... expected_then_found) const {
    ::amt::fail(source_, ":", token_line_, ": ", field, ": expected ", expected_then_found...);
  }

 private:
  // The line of the last character that is not white space (for messages at the end of the text).
  int last_content_line() const {
    int line = line_;
    for (size_t k = text_.size(); k > 0 && is_space(text_[k - 1]); --k) line -= text_[k - 1] == '\n';
    return std::max(line, 1);
  }

  void skip_space() {
    while (pos_ < text_.size() && is_space(text_[pos_])) {
      if (text_[pos_] == '\n') ++line_;
      ++pos_;
    }
  }

  std::string_view text_;
  const std::string& source_;
  size_t pos_ = 0;
  int line_ = 1;
  int token_line_ = 1;
};

class BvhParser {
 public:
  BvhParser(std::string_view text, const std::string& source) : in_(text, source) { file_.source = source; }

  BvhFile parse() {
    expect_keyword("HIERARCHY", "file", "HIERARCHY at the start of a BVH file");
    const std::string_view root = in_.next();
    if (!iequals(root, "ROOT")) in_.fail("HIERARCHY", "ROOT and the root joint's name, found ", quoted(root));
    parse_hierarchy();
    parse_motion();
    return std::move(file_);
  }

 private:
  void expect_keyword(std::string_view keyword, const std::string& field, const std::string& what) {
    const std::string_view token = in_.next();
    if (!iequals(token, keyword)) in_.fail(field, what, ", found ", quoted(token));
  }

  Eigen::Vector3d parse_offset(const std::string& owner) {
    const std::string_view keyword = in_.next();
    if (!iequals(keyword, "OFFSET")) in_.fail(owner, "OFFSET x y z, found ", quoted(keyword));
    Eigen::Vector3d offset;
    for (int k = 0; k < 3; ++k) {
      const std::string_view token = in_.next();
      if (!parse_number(token, offset[k])) {
        in_.fail("OFFSET of " + owner, "3 numbers in [-1e9, 1e9], found ", quoted(token), " as number ", k + 1);
      }
    }
    return offset;
  }

  // "ROOT name" or "JOINT name" has been read up to the name: the name, "{", OFFSET, CHANNELS.
  void parse_joint_header(int parent, const std::string& keyword) {
    const std::string name(in_.rest_of_line());
    if (name.empty()) in_.fail(keyword, "a joint name on the same line, found end of line");
    for (const char c : name) {
      const unsigned char byte = static_cast<unsigned char>(c);
      if (byte < 0x20 || byte == 0x7F) in_.fail(keyword, "a joint name of printable characters, found ", quoted(name));
    }
    const int line = in_.line();
    const auto [seen, inserted] = first_line_.emplace(name, line);
    if (!inserted)
      in_.fail(keyword, "a unique joint name, found '", name, "' again (first at line ", seen->second, ")");
    if (static_cast<int>(file_.joints.size()) >= kMaxJoints)
      in_.fail(keyword, "at most ", kMaxJoints, " joints, found more");

    const std::string_view brace = in_.next();
    if (brace != "{") in_.fail(keyword + " " + name, "'{', found ", quoted(brace));
    BvhJoint joint;
    joint.name = name;
    joint.parent = parent;
    joint.offset = parse_offset("joint '" + name + "'");
    joint.first_column = file_.num_channels;
    if (iequals(in_.peek(), "CHANNELS")) {
      in_.next();
      const std::string field = "CHANNELS of '" + name + "'";
      const std::string_view count_token = in_.next();
      long long count = -1;
      if (!parse_integer(count_token, count) || count < 0 || count > kMaxChannelsPerJoint) {
        in_.fail(field, "a channel count from 0 to ", kMaxChannelsPerJoint, ", found ", quoted(count_token));
      }
      for (long long k = 0; k < count; ++k) {
        const std::string_view token = in_.next();
        BvhChannel channel;
        if (!channel_from_name(token, channel)) {
          in_.fail(field, "one of Xposition, Yposition, Zposition, Xrotation, Yrotation, Zrotation, found ",
                   quoted(token));
        }
        if (std::find(joint.channels.begin(), joint.channels.end(), channel) != joint.channels.end()) {
          in_.fail(field, "each channel at most once, found ", quoted(token), " twice");
        }
        joint.channels.push_back(channel);
      }
      file_.num_channels += static_cast<int>(count);
    }
    file_.joints.push_back(std::move(joint));
  }

  void parse_hierarchy() {
    parse_joint_header(-1, "ROOT");
    std::vector<int> open = {0};  // joints whose block is open, innermost last
    while (!open.empty()) {
      const std::string_view token = in_.next();
      const std::string owner = file_.joints[open.back()].name;
      if (iequals(token, "JOINT")) {
        parse_joint_header(open.back(), "JOINT");
        open.push_back(static_cast<int>(file_.joints.size()) - 1);
      } else if (iequals(token, "End")) {
        const std::string_view site = in_.next();
        if (!iequals(site, "Site")) in_.fail("End Site of '" + owner + "'", "'Site' after 'End', found ", quoted(site));
        const std::string_view brace = in_.next();
        if (brace != "{") in_.fail("End Site of '" + owner + "'", "'{', found ", quoted(brace));
        BvhEndSite end_site;
        end_site.parent = open.back();
        end_site.offset = parse_offset("End Site of '" + owner + "'");
        const std::string_view close = in_.next();
        if (close != "}") in_.fail("End Site of '" + owner + "'", "'}' after its OFFSET, found ", quoted(close));
        file_.end_sites.push_back(end_site);
      } else if (token == "}") {
        open.pop_back();
      } else {
        in_.fail("joint '" + owner + "'", "JOINT, End Site or '}', found ", quoted(token));
      }
    }
  }

  // "Frames:" or "Frames :" (and the same for "Time:").
  void expect_label(std::string_view word, const std::string& field) {
    const std::string_view token = in_.next();
    const std::string label = std::string(word) + ":";
    if (iequals(token, label)) return;
    if (iequals(token, word) && in_.peek() == ":") {
      in_.next();
      return;
    }
    in_.fail(field, "'", label, "', found ", quoted(token));
  }

  void parse_motion() {
    const std::string_view token = in_.next();
    if (iequals(token, "ROOT")) {
      in_.fail("HIERARCHY", "one ROOT (a single skeleton), found a second ROOT");
    }
    if (!iequals(token, "MOTION"))
      in_.fail("HIERARCHY", "MOTION after the root joint's closing '}', found ", quoted(token));
    if (file_.num_channels == 0) in_.fail("CHANNELS", "at least one channel in the hierarchy, found none");
    const int C = file_.num_channels;

    expect_label("Frames", "MOTION");
    const std::string_view frames_token = in_.next();
    long long frames = 0;
    if (!parse_integer(frames_token, frames) || frames < 1) {
      in_.fail("Frames", "a whole number of frames >= 1, found ", quoted(frames_token));
    }
    // Every frame takes at least 2 bytes per value (a digit and a separator): check the count against
    // what is left of the text before allocating anything.
    const unsigned long long max_frames = (static_cast<unsigned long long>(in_.remaining()) + 1) / (2ull * C);
    if (static_cast<unsigned long long>(frames) > max_frames) {
      in_.fail("Frames", "at most ", max_frames, " frames of ", C, " values in the ", in_.remaining(),
               " bytes left in the file, found ", frames);
    }
    if (frames > INT_MAX) in_.fail("Frames", "at most ", INT_MAX, " frames, found ", frames);
    file_.num_frames = static_cast<int>(frames);

    const std::string_view frame_word = in_.next();
    if (!iequals(frame_word, "Frame")) in_.fail("MOTION", "'Frame Time:', found ", quoted(frame_word));
    expect_label("Time", "MOTION");
    const std::string_view time_token = in_.next();
    double frame_time = 0;
    if (!parse_number(time_token, frame_time) || frame_time < kMinFrameTime || frame_time > kMaxFrameTime) {
      in_.fail("Frame Time", "seconds per frame in [", kMinFrameTime, ", ", kMaxFrameTime, "], found ",
               quoted(time_token));
    }
    file_.frame_time = frame_time;
    const std::string_view after_time = in_.rest_of_line_raw();
    if (!after_time.empty()) in_.fail("Frame Time", "the end of the line, found ", quoted(after_time));

    // The column names, for messages.
    std::vector<std::pair<int, BvhChannel>> columns;
    columns.reserve(C);
    for (int j = 0; j < static_cast<int>(file_.joints.size()); ++j) {
      for (BvhChannel c : file_.joints[j].channels) columns.emplace_back(j, c);
    }

    file_.values.resize(static_cast<size_t>(frames) * C);
    double* value = file_.values.data();
    for (long long t = 0; t < frames; ++t) {
      // The next line that is not blank.
      bool found = false;
      while (in_.next_line()) {
        if (!in_.at_end_of_line()) {
          found = true;
          break;
        }
      }
      const auto frame_field = [&] { return detail::concat("frame ", t + 1, " of ", frames); };
      if (!found)
        in_.fail(frame_field(), frames, " frames (Frames: ", frames, ") of ", C, " values, found ", t, " frames");
      for (int c = 0; c < C; ++c) {
        const std::string_view token = in_.next_on_line();
        if (token.empty()) in_.fail(frame_field(), C, " values on the line, found ", c);
        if (!parse_number(token, *value++)) {
          const auto& [joint, channel] = columns[c];
          in_.fail(frame_field() + " (" + file_.joints[joint].name + " " + bvh_channel_name(channel) + ")",
                   "a number in [-1e9, 1e9], found ", quoted(token));
        }
      }
      if (!in_.at_end_of_line()) {
        in_.fail(frame_field(), C, " values on the line, found more: ", quoted(in_.next_on_line()));
      }
    }
    while (in_.next_line()) {
      if (!in_.at_end_of_line()) {
        in_.fail("MOTION", frames, " frames (Frames: ", frames,
                 "), found more data lines: ", quoted(in_.rest_of_line_raw()));
      }
    }
  }

  Cursor in_;
  BvhFile file_;
  std::unordered_map<std::string, int> first_line_;
};

// Rest positions of the joints, then the End Sites, in file units (not lifted).
std::vector<Eigen::Vector3d> rest_points(const BvhFile& file) {
  std::vector<Eigen::Vector3d> points(file.joints.size() + file.end_sites.size());
  for (size_t j = 0; j < file.joints.size(); ++j) {
    const BvhJoint& joint = file.joints[j];
    points[j] = joint.parent < 0 ? joint.offset : points[joint.parent] + joint.offset;
  }
  for (size_t e = 0; e < file.end_sites.size(); ++e) {
    points[file.joints.size() + e] = points[file.end_sites[e].parent] + file.end_sites[e].offset;
  }
  return points;
}

// Largest side of the bounding box of the rest points, file units.
double rest_extent(const std::vector<Eigen::Vector3d>& points) {
  Eigen::Vector3d low = points[0], high = points[0];
  for (const Eigen::Vector3d& p : points) low = low.cwiseMin(p), high = high.cwiseMax(p);
  return (high - low).maxCoeff();
}

// A BvhFile built by hand (not by parse_bvh) gets the parser's guarantees checked before use.
void check_file(const BvhFile& file) {
  const std::string& f = file.source;
  AMT_CHECK(!file.joints.empty(), f, ": HIERARCHY: expected at least one joint, found none");
  AMT_CHECK(file.num_frames > 0 && file.num_channels > 0 &&
                file.values.size() == static_cast<size_t>(file.num_frames) * file.num_channels,
            f, ": MOTION: expected frames x channels values, found ", file.values.size(), " values for ",
            file.num_frames, " frames of ", file.num_channels, " channels");
  AMT_CHECK(file.frame_time >= kMinFrameTime && file.frame_time <= kMaxFrameTime, f,
            ": Frame Time: expected seconds per frame in [", kMinFrameTime, ", ", kMaxFrameTime, "], found ",
            file.frame_time);
  for (size_t j = 0; j < file.joints.size(); ++j) {
    const BvhJoint& joint = file.joints[j];
    const int limit = static_cast<int>(j);
    AMT_CHECK(j == 0 ? joint.parent == -1 : joint.parent >= 0 && joint.parent < limit, f, ": joint '", joint.name,
              "': expected a parent in [0, ", j, ") (-1 for joint 0), found ", joint.parent);
    AMT_CHECK(
        joint.first_column >= 0 && joint.first_column + static_cast<int>(joint.channels.size()) <= file.num_channels, f,
        ": joint '", joint.name, "': expected its channels within the ", file.num_channels,
        " columns, found columns from ", joint.first_column);
  }
  for (const BvhEndSite& end_site : file.end_sites) {
    AMT_CHECK(end_site.parent >= 0 && end_site.parent < static_cast<int>(file.joints.size()), f,
              ": End Site: expected a parent joint in [0, ", file.joints.size(), "), found ", end_site.parent);
  }
}

}  // namespace

// === The raw file

const char* bvh_channel_name(BvhChannel channel) {
  switch (channel) {
    case BvhChannel::kXposition:
      return "Xposition";
    case BvhChannel::kYposition:
      return "Yposition";
    case BvhChannel::kZposition:
      return "Zposition";
    case BvhChannel::kXrotation:
      return "Xrotation";
    case BvhChannel::kYrotation:
      return "Yrotation";
    case BvhChannel::kZrotation:
      return "Zrotation";
  }
  return "?";
}

double BvhFile::fps() const {
  const double rate = 1.0 / frame_time;
  const double nearest = std::round(rate);
  return nearest >= 1 && std::abs(rate - nearest) <= 1e-4 * rate ? nearest : rate;
}

BvhFile parse_bvh(std::string_view text, const std::string& source) {
  return BvhParser(text, source).parse();
}

BvhFile read_bvh(const std::string& path) {
  check_input_file(path, "a BVH motion");
  std::ifstream in(path, std::ios::binary);
  AMT_CHECK(in.good(), path, ": file: expected a readable BVH file, found an error (", std::strerror(errno), ")");
  std::ostringstream text;
  text << in.rdbuf();
  return parse_bvh(text.str(), path);
}

// === Units

BvhUnits detect_bvh_units(const BvhFile& file) {
  check_file(file);
  const double extent = rest_extent(rest_points(file));
  AMT_CHECK(std::isfinite(extent) && extent > 0, file.source,
            ": scale: expected a rest pose of non-zero, finite size to detect the units from, found ", extent,
            "; pass --bvh-scale");
  struct Candidate {
    const char* name;
    double metres_per_unit;
  };
  static const Candidate candidates[] = {
      {"metres", 1.0},    {"decimetres", 0.1},   {"CMU units (1/0.45 inch)", 0.0254 / 0.45},
      {"inches", 0.0254}, {"centimetres", 0.01}, {"millimetres", 0.001}};
  constexpr double kHumanHeight = 1.7;  // metres
  BvhUnits best;
  double best_error = std::numeric_limits<double>::infinity();
  for (const Candidate& c : candidates) {
    const double error = std::abs(std::log(extent * c.metres_per_unit / kHumanHeight));
    if (error < best_error) best_error = error, best = {c.metres_per_unit, c.name, extent};
  }
  return best;
}

// === Conversion to amt's data model

BvhMotion bvh_to_motion(const BvhFile& file, double metres_per_unit) {
  check_file(file);
  AMT_CHECK(std::isfinite(metres_per_unit) && metres_per_unit > 0 && metres_per_unit <= kMaxScale, file.source,
            ": scale: expected metres per file unit in (0, ", kMaxScale, "], found ", metres_per_unit);
  const int B = static_cast<int>(file.joints.size()), E = static_cast<int>(file.end_sites.size()), J = B + E;
  const int T = file.num_frames;
  AMT_CHECK(static_cast<double>(T) * J <= kMaxJointFrames, file.source, ": MOTION: expected at most ", kMaxJointFrames,
            " frames x joints (End Sites included), found ", T, " x ", J);

  BvhMotion out;
  Skeleton& skeleton = out.skeleton;
  std::unordered_set<std::string> taken;
  for (const BvhJoint& joint : file.joints) {
    skeleton.names.push_back(joint.name);
    skeleton.parents.push_back(joint.parent);
    taken.insert(joint.name);
  }
  for (const BvhEndSite& end_site : file.end_sites) {
    std::string name = file.joints[end_site.parent].name + " End";
    for (int k = 2; taken.count(name); ++k) name = file.joints[end_site.parent].name + " End " + std::to_string(k);
    taken.insert(name);
    skeleton.names.push_back(name);
    skeleton.parents.push_back(end_site.parent);
  }
  const std::vector<Eigen::Vector3d> points = rest_points(file);
  double lowest = points[0].y();
  for (const Eigen::Vector3d& p : points) lowest = std::min(lowest, p.y());
  const Eigen::Vector3d lift(0.0, -lowest, 0.0);  // puts the lowest rest point on y = 0
  skeleton.rest_joints.resize(J, 3);
  for (int j = 0; j < J; ++j)
    skeleton.rest_joints.row(j) = ((points[j] + lift) * metres_per_unit).cast<float>().transpose();

  out.motion = rest_motion(skeleton, T, static_cast<float>(file.fps()));
  static const Eigen::Vector3d axes[3] = {Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitZ()};
  for (int t = 0; t < T; ++t) {
    for (int j = 0; j < B; ++j) {
      const BvhJoint& joint = file.joints[j];
      Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
      Eigen::Vector3d position = joint.offset;
      bool has_position = false;
      for (size_t k = 0; k < joint.channels.size(); ++k) {
        const double v = file.value(t, joint.first_column + static_cast<int>(k));
        const BvhChannel channel = joint.channels[k];
        if (is_rotation(channel)) {
          rotation = rotation * Eigen::Quaterniond(Eigen::AngleAxisd(v * kDegrees, axes[axis_of(channel)]));
        } else {
          position[axis_of(channel)] = v;
          has_position = true;
        }
      }
      out.motion.rotation(t, j) = rotation.normalized().cast<float>();
      if (j == 0) {
        // World position (file units) minus the lifted rest position, in metres.
        out.motion.root_translation.row(t) =
            ((position - joint.offset - lift) * metres_per_unit).cast<float>().transpose();
      } else if (has_position) {
        out.dropped_translation = std::max(out.dropped_translation, (position - joint.offset).norm() * metres_per_unit);
      }
    }
  }
  return out;
}


// === Import onto the canonical skeleton

bool is_calibration_frame(const Motion& motion) {
  const int T = motion.num_frames(), J = motion.num_joints();
  if (T < 3 || J == 0) return false;
  auto mean_angle_degrees = [&](int t) {
    double sum = 0.0;
    for (int j = 0; j < J; ++j) sum += Eigen::AngleAxisd(motion.rotation(t, j).cast<double>()).angle();
    return sum / J * 180.0 / 3.14159265358979;
  };
  std::vector<double> take;
  for (int t = 1; t < std::min(T, 31); ++t) take.push_back(mean_angle_degrees(t));
  std::nth_element(take.begin(), take.begin() + take.size() / 2, take.end());
  const double first = mean_angle_degrees(0), median = take[take.size() / 2];
  return first < 10.0 && first < median / 3.0;
}

BvhImport bvh_to_canonical(const BvhFile& file, const BvhImportOptions& options) {
  check_file(file);
  BvhImport out;
  if (options.scale) {
    AMT_CHECK(std::isfinite(*options.scale) && *options.scale > 0 && *options.scale <= kMaxScale, file.source,
              ": --bvh-scale: expected metres per file unit in (0, ", kMaxScale, "], found ", *options.scale);
    out.units.metres_per_unit = *options.scale;
    out.units.name = "given";
    out.units.rest_extent = rest_extent(rest_points(file));
  } else {
    out.units = detect_bvh_units(file);
  }
  if (options.fps) {
    AMT_CHECK(std::isfinite(*options.fps) && *options.fps > 0 && *options.fps <= 1000, file.source,
              ": fps: expected an output frame rate in (0, 1000], found ", *options.fps);
  }
  out.source_fps = file.fps();
  out.source_frames = file.num_frames;

  const BvhMotion full = bvh_to_motion(file, out.units.metres_per_unit);
  out.dropped_translation = full.dropped_translation;
  const JointMapping mapping =
      map_to_canonical(full.skeleton.names, full.skeleton.parents, options.joint_map, file.source);
  out.canonical = to_canonical(full.skeleton, full.motion, mapping, file.source);
  if (options.drop_calibration_frame && is_calibration_frame(out.canonical.motion)) {
    Motion& motion = out.canonical.motion;
    const int J = motion.num_joints(), T = motion.num_frames();
    motion.local_rotations.erase(motion.local_rotations.begin(), motion.local_rotations.begin() + J);
    motion.root_translation = MatrixX3f(motion.root_translation.bottomRows(T - 1));
    out.dropped_calibration_frame = true;
  }
  if (options.fps) out.canonical.motion = resample_motion(out.canonical.motion, *options.fps);
  return out;
}

BvhImport import_bvh(const std::string& path, const BvhImportOptions& options) {
  return bvh_to_canonical(read_bvh(path), options);
}

}  // namespace amt
