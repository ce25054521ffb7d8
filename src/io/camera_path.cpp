// .cam camera path reading and writing (see header for the format).
#include "src/io/camera_path.h"

#include <fmt/format.h>

#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>

namespace frontier {
namespace {

constexpr int kNumbersPerFrame = 10;

bool finite(const Vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

}  // namespace

std::string camera_frame_problem(const Camera& cam) {
  if (!finite(cam.eye) || !finite(cam.look_at) || !finite(cam.up) || !std::isfinite(cam.vfov_deg))
    return "non-finite number";
  if (!(cam.vfov_deg > 0.0 && cam.vfov_deg < 180.0))
    return fmt::format("vertical field of view {} is not in (0, 180) degrees", cam.vfov_deg);
  const Vec3 dir = cam.look_at - cam.eye;
  const double dir_len = glm::length(dir), up_len = glm::length(cam.up);
  if (!(dir_len > 0.0)) return "look-at point equals the eye";
  if (!(up_len > 0.0)) return "up vector is zero";
  const double sine = glm::length(glm::cross(dir / dir_len, cam.up / up_len));
  if (!(sine > 1e-9)) return "up vector is parallel to the viewing direction";
  return {};
}

std::string format_camera_path(const std::vector<Camera>& frames,
                               const std::vector<std::string>& comments) {
  std::string out;
  for (const std::string& c : comments) {
    std::istringstream lines(c);
    std::string line;
    while (std::getline(lines, line)) out += "# " + line + "\n";
  }
  auto it = std::back_inserter(out);
  for (const Camera& c : frames)
    fmt::format_to(it, "{} {} {}  {} {} {}  {} {} {}  {}\n", c.eye.x, c.eye.y, c.eye.z,
                   c.look_at.x, c.look_at.y, c.look_at.z, c.up.x, c.up.y, c.up.z, c.vfov_deg);
  return out;
}

Status write_camera_path(const std::string& path, const std::vector<Camera>& frames,
                         const std::vector<std::string>& comments) {
  for (size_t i = 0; i < frames.size(); ++i) {
    const std::string problem = camera_frame_problem(frames[i]);
    if (!problem.empty())
      return Status::invalid_argument(fmt::format("{}: frame {}: {}", path, i, problem));
  }
  const std::string text = format_camera_path(frames, comments);
  std::FILE* f = path == "-" ? stdout : std::fopen(path.c_str(), "wb");
  if (f == nullptr)
    return Status::io_error(fmt::format("cannot create '{}': {}", path, std::strerror(errno)));
  bool ok = std::fwrite(text.data(), 1, text.size(), f) == text.size();
  ok = (std::fflush(f) == 0) && ok;
  if (f != stdout) ok = (std::fclose(f) == 0) && ok;
  if (!ok) return Status::io_error(fmt::format("writing '{}': {}", path, std::strerror(errno)));
  return Status::ok();
}

Result<std::vector<Camera>> parse_camera_path(std::string_view text, const std::string& name) {
  std::vector<Camera> frames;
  size_t line_no = 0, pos = 0;
  while (pos < text.size()) {
    size_t end = text.find('\n', pos);
    if (end == std::string_view::npos) end = text.size();
    std::string_view line = text.substr(pos, end - pos);
    pos = end + 1;
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);

    double v[kNumbersPerFrame];
    int count = 0;
    size_t i = 0;
    bool comment = false;
    while (true) {
      while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
      if (i >= line.size()) break;
      if (count == 0 && line[i] == '#') {
        comment = true;
        break;
      }
      size_t j = i;
      while (j < line.size() && line[j] != ' ' && line[j] != '\t') ++j;
      const std::string_view token = line.substr(i, j - i);
      if (count == kNumbersPerFrame)
        return Status::corruption(fmt::format("{}: line {}: more than {} numbers", name, line_no,
                                              kNumbersPerFrame));
      const char* first = token.data();
      if (!token.empty() && token[0] == '+') ++first;  // from_chars rejects a leading '+'
      const auto [ptr, ec] = std::from_chars(first, token.data() + token.size(), v[count]);
      if (ec != std::errc() || ptr != token.data() + token.size())
        return Status::corruption(
            fmt::format("{}: line {}: '{}' is not a number", name, line_no, token));
      ++count;
      i = j;
    }
    if (comment || count == 0) continue;
    if (count != kNumbersPerFrame)
      return Status::corruption(fmt::format(
          "{}: line {}: expected {} numbers (eye, look-at, up, vfov), got {}", name, line_no,
          kNumbersPerFrame, count));
    Camera cam;
    cam.eye = Vec3(v[0], v[1], v[2]);
    cam.look_at = Vec3(v[3], v[4], v[5]);
    cam.up = Vec3(v[6], v[7], v[8]);
    cam.vfov_deg = v[9];
    const std::string problem = camera_frame_problem(cam);
    if (!problem.empty())
      return Status::corruption(fmt::format("{}: line {}: {}", name, line_no, problem));
    frames.push_back(cam);
  }
  return frames;
}

Result<std::vector<Camera>> read_camera_path(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::not_found(fmt::format("cannot open '{}': {}", path, std::strerror(errno)));
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) return Status::io_error(fmt::format("reading '{}' failed", path));
  return parse_camera_path(text.str(), path);
}

}  // namespace frontier
