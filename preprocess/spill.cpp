// Spill files (layout in spill.h).
#include "preprocess/spill.h"

#include <fmt/format.h>

#include <cerrno>
#include <cstring>

namespace frontier {
namespace {

constexpr size_t kBufferBytes = 4 << 20;
constexpr size_t kRecordHeader = 12;

constexpr size_t geometry_doubles(PrimKind kind, bool normals) {
  switch (kind) {
    case PrimKind::Triangle: return normals ? 18 : 9;
    case PrimKind::Sphere: return 4;
    case PrimKind::Box: return 6;
    case PrimKind::Cone: return 8;
    case PrimKind::Quadric: return 10 + 4 * Quadric::kMaxClipPlanes + 6 + 1;
  }
  return 0;
}

constexpr size_t kLargestRecord = kRecordHeader + 8 * geometry_doubles(PrimKind::Quadric, false);

// Appends at `at` (the writer's buffer always has room for one more record).
void put(uint8_t*& at, const double* values, size_t n) {
  std::memcpy(at, values, n * sizeof(double));
  at += n * sizeof(double);
}
void put(uint8_t*& at, const Vec3& v) { put(at, &v.x, 3); }

}  // namespace

SpillWriter::~SpillWriter() {
  if (file_ != nullptr) std::fclose(file_);
}

Status SpillWriter::open(const std::string& path) {
  path_ = path;
  file_ = std::fopen(path.c_str(), "wb");
  if (file_ == nullptr) return Status::io_error(fmt::format("{}: cannot create: {}", path, std::strerror(errno)));
  buffer_.resize(buffer_bytes_ + kLargestRecord);  // once: records are copied in, never appended
  used_ = 0;
  return Status::ok();
}

Status SpillWriter::write(const Scene& scene, uint32_t i) {
  const PrimRef& p = scene.prims[i];
  const bool normals = p.kind == PrimKind::Triangle && !scene.triangle_normals.empty();
  uint8_t* at = buffer_.data() + used_;
  const uint8_t head[4] = {static_cast<uint8_t>(p.kind), static_cast<uint8_t>(normals), 0, 0};
  std::memcpy(at, head, 4);
  const uint32_t ids[2] = {p.source, p.material};
  std::memcpy(at + 4, ids, 8);
  at += kRecordHeader;
  switch (p.kind) {
    case PrimKind::Triangle: {
      const Triangle& t = scene.triangles[p.index];
      put(at, t.v0);
      put(at, t.v1);
      put(at, t.v2);
      if (normals) {
        for (const Vec3& n : scene.triangle_normals[p.index]) put(at, n);
      }
      break;
    }
    case PrimKind::Sphere: {
      const Sphere& s = scene.spheres[p.index];
      put(at, s.center);
      put(at, &s.radius, 1);
      break;
    }
    case PrimKind::Box:
      put(at, scene.boxes[p.index].bounds.lo);
      put(at, scene.boxes[p.index].bounds.hi);
      break;
    case PrimKind::Cone: {
      const Cone& c = scene.cones[p.index];
      put(at, c.base);
      put(at, &c.base_radius, 1);
      put(at, c.apex);
      put(at, &c.apex_radius, 1);
      break;
    }
    case PrimKind::Quadric: {
      const Quadric& q = scene.quadrics[p.index];
      put(at, q.coeff.data(), 10);
      for (const Vec4& c : q.clip) put(at, &c.x, 4);
      put(at, q.bounds.lo);
      put(at, q.bounds.hi);
      const double count = q.clip_count;
      put(at, &count, 1);
      break;
    }
  }
  used_ = static_cast<size_t>(at - buffer_.data());
  ++records_;
  if (used_ >= buffer_bytes_) return flush();
  return Status::ok();
}

Status SpillWriter::flush() {
  if (used_ == 0) return Status::ok();
  if (std::fwrite(buffer_.data(), 1, used_, file_) != used_) {
    return Status::io_error(fmt::format("{}: write failed: {}", path_, std::strerror(errno)));
  }
  bytes_ += used_;
  used_ = 0;
  return Status::ok();
}

Status SpillWriter::close() {
  if (file_ == nullptr) return Status::ok();
  Status s = flush();
  if (std::fclose(file_) != 0 && s) s = Status::io_error(fmt::format("{}: close failed: {}", path_, std::strerror(errno)));
  file_ = nullptr;
  return s;
}

SpillReader::~SpillReader() {
  if (file_ != nullptr) std::fclose(file_);
}

Status SpillReader::open(const std::string& path) {
  path_ = path;
  file_ = std::fopen(path.c_str(), "rb");
  if (file_ == nullptr) return Status::io_error(fmt::format("{}: cannot open: {}", path, std::strerror(errno)));
  buffer_.resize(kBufferBytes);
  return Status::ok();
}

Status SpillReader::fill() {
  // Keep the unread tail, then top the buffer up.
  std::memmove(buffer_.data(), buffer_.data() + begin_, end_ - begin_);
  end_ -= begin_;
  begin_ = 0;
  while (!eof_ && end_ < buffer_.size()) {
    const size_t got = std::fread(buffer_.data() + end_, 1, buffer_.size() - end_, file_);
    if (got == 0) {
      if (std::ferror(file_)) return Status::io_error(fmt::format("{}: read failed: {}", path_, std::strerror(errno)));
      eof_ = true;
    }
    end_ += got;
  }
  return Status::ok();
}

Status SpillReader::read(Scene& batch, size_t max, bool& end) {
  end = false;
  for (size_t n = 0; n < max; ++n) {
    if (end_ - begin_ < kLargestRecord && !eof_) {
      if (Status s = fill(); !s) return s;
    }
    if (begin_ == end_) {
      end = true;
      return Status::ok();
    }
    if (end_ - begin_ < kRecordHeader) return Status::corruption(fmt::format("{}: torn record", path_));
    const uint8_t* p = buffer_.data() + begin_;
    if (p[0] > static_cast<uint8_t>(PrimKind::Quadric)) return Status::corruption(fmt::format("{}: bad record", path_));
    const auto kind = static_cast<PrimKind>(p[0]);
    const bool normals = p[1] != 0;
    uint32_t ids[2];
    std::memcpy(ids, p + 4, 8);
    const size_t count = geometry_doubles(kind, normals);
    if (end_ - begin_ < kRecordHeader + 8 * count) return Status::corruption(fmt::format("{}: torn record", path_));
    double g[10 + 4 * Quadric::kMaxClipPlanes + 6 + 1];
    std::memcpy(g, p + kRecordHeader, 8 * count);
    begin_ += kRecordHeader + 8 * count;
    const uint32_t source = ids[0], material = ids[1];
    switch (kind) {
      case PrimKind::Triangle: {
        const Triangle t{{g[0], g[1], g[2]}, {g[3], g[4], g[5]}, {g[6], g[7], g[8]}};
        if (normals) {
          const std::array<Vec3, 3> nn = {Vec3(g[9], g[10], g[11]), Vec3(g[12], g[13], g[14]), Vec3(g[15], g[16], g[17])};
          batch.add_triangle(t, source, material, &nn);
        } else {
          batch.add_triangle(t, source, material);
        }
        break;
      }
      case PrimKind::Sphere: batch.add_sphere({{g[0], g[1], g[2]}, g[3]}, source, material); break;
      case PrimKind::Box: batch.add_box({Aabb({g[0], g[1], g[2]}, {g[3], g[4], g[5]})}, source, material); break;
      case PrimKind::Cone: batch.add_cone({{g[0], g[1], g[2]}, g[3], {g[4], g[5], g[6]}, g[7]}, source, material); break;
      case PrimKind::Quadric: {
        Quadric q;
        std::memcpy(q.coeff.data(), g, 10 * 8);
        for (int c = 0; c < Quadric::kMaxClipPlanes; ++c) {
          q.clip[static_cast<size_t>(c)] = Vec4(g[10 + 4 * c], g[11 + 4 * c], g[12 + 4 * c], g[13 + 4 * c]);
        }
        const double* b = g + 10 + 4 * Quadric::kMaxClipPlanes;
        q.bounds = Aabb({b[0], b[1], b[2]}, {b[3], b[4], b[5]});
        q.clip_count = static_cast<int>(b[6]);
        batch.add_quadric(q, source, material);
        break;
      }
    }
  }
  return Status::ok();
}

}  // namespace frontier
