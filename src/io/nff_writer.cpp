// NFF text writer with a bounded buffer (see header).
#include "src/io/nff_writer.h"

#include "src/io/staging_path.h"

#include <fmt/format.h>

#include <cerrno>
#include <cstring>
#include <iterator>

#include <unistd.h>

namespace frontier {
namespace {

constexpr size_t kFlushBytes = size_t{1} << 20;

void put(std::string& out, const Vec3& v) {
  fmt::format_to(std::back_inserter(out), "{:.9g} {:.9g} {:.9g}", v.x, v.y, v.z);
}

}  // namespace

Result<std::unique_ptr<NffWriter>> NffWriter::create(const std::string& path) {
  std::unique_ptr<NffWriter> w(new NffWriter());
  w->path_ = path;
  if (path == "-") {
    w->file_ = stdout;
  } else {
    const std::string staging = staging_path(path);
    const std::string& target = staging.empty() ? path : staging;
    w->file_ = std::fopen(target.c_str(), "wb");
    if (w->file_ == nullptr)
      return Status::io_error(fmt::format("cannot create '{}': {}", target, std::strerror(errno)));
    w->owns_file_ = true;
    w->temp_path_ = staging;
  }
  w->buffer_.reserve(kFlushBytes + 4096);
  return w;
}

NffWriter::~NffWriter() {
  if (owns_file_ && file_ != nullptr) std::fclose(file_);
  if (!finished_ && !temp_path_.empty()) ::unlink(temp_path_.c_str());
}

bool NffWriter::check(bool ok, std::string_view what) {
  if (!ok && error_.is_ok())
    error_ = Status::invalid_argument(
        fmt::format("{}: {} (after {} primitives): NaN, Inf or non-positive size", path_, what,
                    primitives_));
  return ok;
}

void NffWriter::flush_if_full() {
  if (buffer_.size() < kFlushBytes) return;
  if (error_.is_ok() && std::fwrite(buffer_.data(), 1, buffer_.size(), file_) != buffer_.size())
    error_ = Status::io_error(fmt::format("writing '{}': {}", path_, std::strerror(errno)));
  buffer_.clear();
}

void NffWriter::comment(std::string_view text) {
  size_t start = 0;
  while (start <= text.size()) {
    const size_t end = std::min(text.find('\n', start), text.size());
    fmt::format_to(std::back_inserter(buffer_), "# {}\n", text.substr(start, end - start));
    start = end + 1;
  }
  flush_if_full();
}

void NffWriter::view(const Camera& cam, double hither, int width, int height) {
  if (!check(finite(cam.eye) && finite(cam.look_at) && finite(cam.up) &&
                 std::isfinite(cam.vfov_deg) && cam.vfov_deg > 0.0 && std::isfinite(hither) &&
                 width > 0 && height > 0,
             "view"))
    return;
  auto out = std::back_inserter(buffer_);
  buffer_ += "v\nfrom ";
  put(buffer_, cam.eye);
  buffer_ += "\nat ";
  put(buffer_, cam.look_at);
  buffer_ += "\nup ";
  put(buffer_, cam.up);
  fmt::format_to(out, "\nangle {:.9g}\nhither {:.9g}\nresolution {} {}\n", cam.vfov_deg, hither,
                 width, height);
  flush_if_full();
}

void NffWriter::background(const Vec3& rgb) {
  if (!check(finite(rgb), "background")) return;
  buffer_ += "b ";
  put(buffer_, rgb);
  buffer_ += '\n';
}

void NffWriter::light(const Vec3& position, const Vec3& rgb) {
  if (!check(finite(position) && finite(rgb), "light")) return;
  buffer_ += "l ";
  put(buffer_, position);
  buffer_ += ' ';
  put(buffer_, rgb);
  buffer_ += '\n';
  flush_if_full();
}

void NffWriter::material(const Material& m) {
  const bool ok = finite(m.color) && std::isfinite(m.kd) && std::isfinite(m.ks) &&
                  std::isfinite(m.shine) && std::isfinite(m.transmittance) && std::isfinite(m.ior);
  if (!check(ok, "material")) return;
  buffer_ += "f ";
  put(buffer_, m.color);
  fmt::format_to(std::back_inserter(buffer_), " {:.9g} {:.9g} {:.9g} {:.9g} {:.9g}\n", m.kd, m.ks,
                 m.shine, m.transmittance, m.ior);
  flush_if_full();
}

void NffWriter::sphere(const Vec3& center, double radius) {
  if (!check(finite(center) && std::isfinite(radius) && radius > 0.0, "sphere")) return;
  buffer_ += "s ";
  put(buffer_, center);
  fmt::format_to(std::back_inserter(buffer_), " {:.9g}\n", radius);
  ++primitives_;
  flush_if_full();
}

void NffWriter::cone(const Vec3& base, double base_radius, const Vec3& apex, double apex_radius) {
  const bool ok = finite(base) && finite(apex) && std::isfinite(base_radius) &&
                  std::isfinite(apex_radius) && base_radius >= 0.0 && apex_radius >= 0.0 &&
                  (base_radius > 0.0 || apex_radius > 0.0) && base != apex;
  if (!check(ok, "cone")) return;
  buffer_ += "c ";
  put(buffer_, base);
  fmt::format_to(std::back_inserter(buffer_), " {:.9g} ", base_radius);
  put(buffer_, apex);
  fmt::format_to(std::back_inserter(buffer_), " {:.9g}\n", apex_radius);
  ++primitives_;
  flush_if_full();
}

void NffWriter::polygon(std::span<const Vec3> vertices) {
  bool ok = vertices.size() >= 3;
  for (const Vec3& v : vertices) ok = ok && finite(v);
  if (!check(ok, "polygon")) return;
  fmt::format_to(std::back_inserter(buffer_), "p {}\n", vertices.size());
  for (const Vec3& v : vertices) {
    put(buffer_, v);
    buffer_ += '\n';
  }
  ++primitives_;
  flush_if_full();
}

Status NffWriter::finish() {
  if (finished_) return error_;
  if (error_.is_ok() && !buffer_.empty() &&
      std::fwrite(buffer_.data(), 1, buffer_.size(), file_) != buffer_.size())
    error_ = Status::io_error(fmt::format("writing '{}': {}", path_, std::strerror(errno)));
  buffer_.clear();
  if (error_.is_ok() && std::fflush(file_) != 0)
    error_ = Status::io_error(fmt::format("writing '{}': {}", path_, std::strerror(errno)));
  if (owns_file_) {
    std::FILE* f = file_;
    file_ = nullptr;
    if (std::fclose(f) != 0 && error_.is_ok())
      error_ = Status::io_error(fmt::format("closing '{}': {}", path_, std::strerror(errno)));
  }
  if (!error_.is_ok()) return error_;  // destructor removes PATH.tmp
  if (!temp_path_.empty() && std::rename(temp_path_.c_str(), path_.c_str()) != 0)
    return error_ = Status::io_error(fmt::format("renaming '{}' to '{}': {}", temp_path_, path_,
                                                 std::strerror(errno)));
  finished_ = true;
  return error_;
}

}  // namespace frontier
