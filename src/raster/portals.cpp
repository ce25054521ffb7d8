// PortalGraph: the sidecar reader, the "portals" section codec, the room locator and the
// cells-and-portals traversal (see the header for the model and the guarantees).
#include "src/raster/portals.h"

#include "src/core/byte_io.h"
#include "store/section_frame.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <unordered_map>
#include <unordered_set>

namespace frontier {
namespace {

// --- the section layout (store/FORMAT.md, "portals"; framed by store/section_frame.h) --------
constexpr store::SectionMagic kMagic = {'F', 'P', 'R', 'T'};
constexpr uint32_t kVersion = 1;
constexpr size_t kCountsBytes = 32;             // wall f64, slab f64, room count u64, portal count u64
constexpr size_t kRoomBytes = 48;               // interior lo, hi
constexpr size_t kPortalBytes = 8 + 96 + 48;    // rooms 2 x u32, polygon 4 x xyz, opening lo, hi

// Visits to one room before new rectangles are widened to cover the earlier ones.
constexpr size_t kVisitsBeforeWidening = 4;


bool finite(const Vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }
bool proper(const Aabb& b) { return finite(b.lo) && finite(b.hi) && !b.empty(); }

Aabb enlarged(const Aabb& b, const Vec3& by) {
  Aabb r = b;
  r.lo -= by;
  r.hi += by;
  return r;
}

// --- reading the sidecar -------------------------------------------------------------------
using json = nlohmann::json;

Vec3 json_vec(const json& j) {
  if (!j.is_array() || j.size() != 3) throw std::runtime_error("expected [x, y, z]");
  return {j.at(0).get<double>(), j.at(1).get<double>(), j.at(2).get<double>()};
}
Aabb json_box(const json& j) {
  if (!j.is_array() || j.size() != 2) throw std::runtime_error("expected [[x, y, z], [x, y, z]]");
  Aabb b;
  b.lo = json_vec(j.at(0));
  b.hi = json_vec(j.at(1));
  return b;
}
uint64_t json_id(const json& j) {
  if (!j.is_number_unsigned()) throw std::runtime_error("expected a non-negative integer");
  return j.get<uint64_t>();
}

// Parser callback state: room and portal objects are converted as soon as they are complete
// and then dropped from the document, which keeps only the small top-level fields.
class SidecarReader {
 public:
  bool on_event(int depth, json::parse_event_t event, json& parsed) {
    using Event = json::parse_event_t;
    if (event == Event::key && depth == 1) {
      top_key_ = parsed.get<std::string>();
      return true;
    }
    const bool element = top_key_ == "rooms" || top_key_ == "portals";
    if (!element || depth < 2) return true;
    if (event == Event::key && depth == 3) {
      const auto& key = parsed.get_ref<const std::string&>();
      return key == "id" || key == "bounds" || key == "rooms" || key == "polygon" || key == "opening";
    }
    if (depth != 2) return true;
    if (event == Event::object_end) {
      if (error_.empty()) error_ = top_key_ == "rooms" ? add_room(parsed) : add_portal(parsed);
      return false;
    }
    if (event == Event::value || event == Event::array_end) {
      if (error_.empty()) error_ = fmt::format("{}[{}]: not an object", top_key_, count());
      return false;
    }
    return true;
  }

  const std::string& error() const { return error_; }
  std::vector<Aabb>& rooms() { return rooms_; }
  std::vector<PortalGraph::Portal>& portals() { return portals_; }

 private:
  size_t count() const { return top_key_ == "rooms" ? rooms_.size() : portals_.size(); }

  std::string add_room(const json& j) {
    try {
      const uint64_t id = json_id(j.at("id"));
      if (id != rooms_.size()) {
        return fmt::format("rooms[{}]: id {} (ids must be dense and in order)", rooms_.size(), id);
      }
      rooms_.push_back(json_box(j.at("bounds")));
    } catch (const std::exception& e) {
      return fmt::format("rooms[{}]: {}", rooms_.size(), e.what());
    }
    return {};
  }

  std::string add_portal(const json& j) {
    try {
      const uint64_t id = json_id(j.at("id"));
      if (id != portals_.size()) {
        return fmt::format("portals[{}]: id {} (ids must be dense and in order)", portals_.size(), id);
      }
      PortalGraph::Portal p;
      const json& rooms = j.at("rooms");
      if (!rooms.is_array() || rooms.size() != 2) throw std::runtime_error("rooms: expected [a, b]");
      for (int k = 0; k < 2; ++k) {
        const uint64_t room = json_id(rooms.at(k));
        if (room > UINT32_MAX) throw std::runtime_error(fmt::format("room {} out of range", room));
        p.rooms[k] = static_cast<uint32_t>(room);
      }
      const json& polygon = j.at("polygon");
      if (!polygon.is_array() || polygon.size() != 4) throw std::runtime_error("polygon: expected 4 corners");
      for (int k = 0; k < 4; ++k) p.polygon[k] = json_vec(polygon.at(k));
      p.opening = json_box(j.at("opening"));
      portals_.push_back(p);
    } catch (const std::exception& e) {
      return fmt::format("portals[{}]: {}", portals_.size(), e.what());
    }
    return {};
  }

  std::string top_key_;
  std::string error_;
  std::vector<Aabb> rooms_;
  std::vector<PortalGraph::Portal> portals_;
};

// --- pixel rectangles and the projection of portals ------------------------------------------
struct Rect {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // [x0, x1) x [y0, y1)

  bool empty() const { return x0 >= x1 || y0 >= y1; }
  bool contains(const Rect& r) const { return x0 <= r.x0 && y0 <= r.y0 && x1 >= r.x1 && y1 >= r.y1; }
  Rect intersection(const Rect& r) const {
    return {std::max(x0, r.x0), std::max(y0, r.y0), std::min(x1, r.x1), std::min(y1, r.y1)};
  }
  Rect hull(const Rect& r) const {
    return {std::min(x0, r.x0), std::min(y0, r.y0), std::max(x1, r.x1), std::max(y1, r.y1)};
  }
};

Rect rect_of(const PortalVisit& v) { return {v.x0, v.y0, v.x1, v.y1}; }

// World to pixel coordinates with the view's own camera: view.direction(x, y) = M (x, y, 1)
// with M's columns step_x, step_y, base, so a point at offset d from the eye has
// M^-1 d = w (x, y, 1), where w > 0 exactly in front of the eye plane (the depth along the
// view axis for Views made from a Camera). Pixel x's centre is at coordinate x.
class Projector {
 public:
  explicit Projector(const View& view) : view_(view) {
    const glm::dmat3 m(view.step_x, view.step_y, view.base);
    const double det = glm::determinant(m);
    invertible_ = std::isnormal(det);
    if (invertible_) to_pixel_ = glm::inverse(m);
  }

  // The part of `current` through which a ray may cross `polygon`.
  Rect narrow(const std::array<Vec3, 4>& polygon, const Rect& current) const {
    if (!invertible_) return current;
    std::array<Vec3, 4> c;
    double w_max = -kInfinity;
    bool near_eye = false;
    for (int k = 0; k < 4; ++k) {
      const Vec3 d = polygon[k] - view_.eye;
      c[k] = to_pixel_ * d;
      const double tiny = 1e-9 * (std::abs(d.x) + std::abs(d.y) + std::abs(d.z));
      near_eye = near_eye || !(c[k].z > std::max(view_.near, tiny));
      w_max = std::max(w_max, c[k].z);
    }
    // Pixel rays are at w > 0 beyond the eye: a polygon wholly at w <= 0 is never crossed.
    if (w_max <= 0.0) return {};
    // Corners at or behind the eye plane project anywhere (or nowhere): no narrowing.
    if (near_eye) return current;
    double x_min = kInfinity, x_max = -kInfinity, y_min = kInfinity, y_max = -kInfinity;
    for (const Vec3& p : c) {
      x_min = std::min(x_min, p.x / p.z);
      x_max = std::max(x_max, p.x / p.z);
      y_min = std::min(y_min, p.y / p.z);
      y_max = std::max(y_max, p.y / p.z);
    }
    // Pixels whose centres lie within one pixel of the projected corners' bounds.
    const auto first = [](double v, int size) { return static_cast<int>(std::ceil(std::clamp(v, -2.0, size + 2.0)) - 1.0); };
    const auto past = [](double v, int size) { return static_cast<int>(std::floor(std::clamp(v, -2.0, size + 2.0)) + 2.0); };
    const Rect r{first(x_min, view_.width), first(y_min, view_.height), past(x_max, view_.width),
                 past(y_max, view_.height)};
    return current.intersection(r);
  }

 private:
  const View& view_;
  glm::dmat3 to_pixel_{1.0};
  bool invertible_ = false;
};

}  // namespace

// --- construction and invariants -------------------------------------------------------------

Result<PortalGraph> PortalGraph::create(std::vector<Aabb> rooms, std::vector<Portal> portals, double wall_thickness,
                                        double slab_thickness) {
  PortalGraph g;
  g.rooms_ = std::move(rooms);
  g.portals_ = std::move(portals);
  g.wall_ = wall_thickness;
  g.slab_ = slab_thickness;
  if (Status s = g.finish(); !s) return s;
  return g;
}

Status PortalGraph::finish() {
  double magnitude = 0.0;
  if (Status s = check_rooms(magnitude); !s) return s;
  if (Status s = orient_portals(magnitude); !s) return s;
  build_adjacency();
  build_locator();
  return Status::ok();
}

Status PortalGraph::check_rooms(double& magnitude) {
  if (!(std::isfinite(wall_) && wall_ >= 0.0 && std::isfinite(slab_) && slab_ >= 0.0)) {
    return Status::corruption(fmt::format("wall thickness {} or slab thickness {} is not a length", wall_, slab_));
  }
  if (rooms_.size() >= UINT32_MAX / 2 || portals_.size() >= UINT32_MAX / 2) {
    return Status::corruption(fmt::format("{} rooms and {} portals: too many", rooms_.size(), portals_.size()));
  }
  magnitude = 0.0;
  for (size_t r = 0; r < rooms_.size(); ++r) {
    if (!proper(rooms_[r])) return Status::corruption(fmt::format("room {}: bounds empty or not finite", r));
    magnitude = std::max(magnitude, rooms_[r].magnitude());
  }
  slack_ = 1e-9 * (1.0 + magnitude);
  return Status::ok();
}

Status PortalGraph::orient_portals(double magnitude) {
  normals_.resize(portals_.size());
  for (size_t i = 0; i < portals_.size(); ++i) {
    const Portal& p = portals_[i];
    const auto [a, b] = p.rooms;
    if (a >= rooms_.size() || b >= rooms_.size()) {
      return Status::corruption(fmt::format("portal {}: room {} out of range ({} rooms)", i, std::max(a, b), rooms_.size()));
    }
    if (a == b) return Status::corruption(fmt::format("portal {}: joins room {} to itself", i, a));
    if (!proper(p.opening)) return Status::corruption(fmt::format("portal {}: opening empty or not finite", i));
    for (const Vec3& v : p.polygon) {
      if (!finite(v)) return Status::corruption(fmt::format("portal {}: polygon corner not finite", i));
    }
    // Twice the area vector of the quadrilateral (cross product of its diagonals).
    Vec3 n = glm::cross(p.polygon[2] - p.polygon[0], p.polygon[3] - p.polygon[1]);
    const double length = glm::length(n);
    if (!(length > 1e-12 * (1.0 + magnitude) * (1.0 + magnitude))) {
      return Status::corruption(fmt::format("portal {}: polygon has no area", i));
    }
    n /= length;
    double side_a = glm::dot(n, rooms_[a].center() - p.polygon[0]);
    if (side_a > 0.0) {
      n = -n;
      side_a = -side_a;
    }
    const double side_b = glm::dot(n, rooms_[b].center() - p.polygon[0]);
    if (!(side_a < 0.0 && side_b > 0.0)) {
      return Status::corruption(fmt::format("portal {}: rooms {} and {} are not on opposite sides of it", i, a, b));
    }
    normals_[i] = n;
  }
  return Status::ok();
}

void PortalGraph::build_adjacency() {
  adjacency_first_.assign(rooms_.size() + 1, 0);
  for (const Portal& p : portals_) {
    for (uint32_t room : p.rooms) ++adjacency_first_[room + 1];
  }
  for (size_t r = 0; r < rooms_.size(); ++r) adjacency_first_[r + 1] += adjacency_first_[r];
  adjacency_.resize(adjacency_first_.back());
  std::vector<uint32_t> fill(adjacency_first_.begin(), adjacency_first_.end() - 1);
  for (uint32_t i = 0; i < portals_.size(); ++i) {
    for (uint32_t room : portals_[i].rooms) adjacency_[fill[room]++] = i;
  }
}

void PortalGraph::build_locator() {
  // The locator: a uniform grid whose cells are about a typical room in size (at most a few
  // cells per box), every box listed in each grid cell it overlaps.
  locator_ = Locator{};
  if (rooms_.empty()) return;
  const uint32_t item_count = static_cast<uint32_t>(rooms_.size() + portals_.size());
  auto item_box = [&](uint32_t item) {
    return item < rooms_.size() ? room_region(item) : doorway(item - static_cast<uint32_t>(rooms_.size()));
  };
  Aabb all;
  Vec3 typical(0.0);
  for (uint32_t item = 0; item < item_count; ++item) all.extend(item_box(item));
  for (uint32_t r = 0; r < rooms_.size(); ++r) typical += room_region(r).extent();
  typical /= static_cast<double>(rooms_.size());
  const Vec3 extent = all.extent();
  const double cell_limit = 4.0 * item_count + 64.0;
  for (;;) {
    double cells = 1.0;
    for (int a = 0; a < 3; ++a) {
      const double n = typical[a] > 0.0 ? std::ceil(extent[a] / typical[a]) : 1.0;
      locator_.dims[a] = static_cast<int>(std::clamp(n, 1.0, cell_limit));
      cells *= locator_.dims[a];
    }
    if (cells <= cell_limit) break;
    typical *= std::max(1.1, std::cbrt(cells / cell_limit));
  }
  locator_.origin = all.lo;
  for (int a = 0; a < 3; ++a) locator_.cell[a] = extent[a] > 0.0 ? extent[a] / locator_.dims[a] : 1.0;
  const size_t cell_count = size_t(locator_.dims[0]) * size_t(locator_.dims[1]) * size_t(locator_.dims[2]);
  auto cell_index = [&](const Vec3& p, int axis) {
    const double t = std::floor((p[axis] - locator_.origin[axis]) / locator_.cell[axis]);
    return static_cast<int>(std::clamp(t, 0.0, double(locator_.dims[axis] - 1)));
  };
  auto for_cells = [&](const Aabb& box, auto&& visit) {
    const std::array<int, 3> lo{cell_index(box.lo, 0), cell_index(box.lo, 1), cell_index(box.lo, 2)};
    const std::array<int, 3> hi{cell_index(box.hi, 0), cell_index(box.hi, 1), cell_index(box.hi, 2)};
    for (int z = lo[2]; z <= hi[2]; ++z)
      for (int y = lo[1]; y <= hi[1]; ++y)
        for (int x = lo[0]; x <= hi[0]; ++x)
          visit((size_t(z) * size_t(locator_.dims[1]) + size_t(y)) * size_t(locator_.dims[0]) + size_t(x));
  };
  locator_.first.assign(cell_count + 1, 0);
  for (uint32_t item = 0; item < item_count; ++item) for_cells(item_box(item), [&](size_t c) { ++locator_.first[c + 1]; });
  for (size_t c = 0; c < cell_count; ++c) locator_.first[c + 1] += locator_.first[c];
  locator_.items.resize(locator_.first.back());
  std::vector<uint32_t> next(locator_.first.begin(), locator_.first.end() - 1);
  for (uint32_t item = 0; item < item_count; ++item) {
    for_cells(item_box(item), [&](size_t c) { locator_.items[next[c]++] = item; });
  }
}

Aabb PortalGraph::room_region(uint32_t room) const {
  return enlarged(rooms_[room], Vec3(0.5 * wall_, 0.5 * wall_, 0.5 * slab_));
}

std::span<const uint32_t> PortalGraph::room_portals(uint32_t room) const {
  return std::span<const uint32_t>(adjacency_).subspan(adjacency_first_[room],
                                                        adjacency_first_[room + 1] - adjacency_first_[room]);
}

Aabb PortalGraph::doorway(uint32_t portal) const { return enlarged(portals_[portal].opening, Vec3(slack_)); }

bool PortalGraph::faces(uint32_t portal, uint32_t room, const Vec3& eye) const {
  const double side = glm::dot(normals_[portal], eye - portals_[portal].polygon[0]);
  // The normal points from rooms[0] to rooms[1]; an eye on (or next to) the plane sees both ways.
  return room == portals_[portal].rooms[0] ? side <= slack_ : side >= -slack_;
}

// --- the sidecar ------------------------------------------------------------------------------

Result<PortalGraph> PortalGraph::from_sidecar(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return Status::not_found(fmt::format("{}: no such file", path));
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::io_error(fmt::format("{}: cannot open: {}", path, std::strerror(errno)));
  SidecarReader reader;
  json head;
  try {
    head = json::parse(in, [&](int depth, json::parse_event_t event, json& parsed) {
      return reader.on_event(depth, event, parsed);
    });
  } catch (const json::exception& e) {
    if (in.bad()) return Status::io_error(fmt::format("{}: read failed", path));
    return Status::corruption(fmt::format("{}: not valid JSON: {}", path, e.what()));
  }
  if (!head.is_object()) return Status::corruption(fmt::format("{}: not a JSON object", path));
  if (!head.contains("rooms") && !head.contains("portals")) {
    return Status::not_found(fmt::format("{}: no rooms and portals", path));
  }
  if (!reader.error().empty()) return Status::corruption(fmt::format("{}: {}", path, reader.error()));
  if (head.contains("format") && head["format"] != "frontier-building") {
    return Status::unsupported(fmt::format("{}: format {} is not frontier-building", path, head["format"].dump()));
  }
  if (head.contains("version") && !(head["version"].is_number_unsigned() && head["version"].get<uint64_t>() <= 1)) {
    return Status::unsupported(fmt::format("{}: sidecar version {} is not 1", path, head["version"].dump()));
  }
  for (const char* key : {"rooms", "portals"}) {
    if (!head.contains(key) || !head[key].is_array()) {
      return Status::corruption(fmt::format("{}: \"{}\" missing or not an array", path, key));
    }
  }
  double thickness[2] = {0.0, 0.0};
  const char* thickness_keys[2] = {"wall_thickness", "slab_thickness"};
  for (int k = 0; k < 2; ++k) {
    const auto it = head.find(thickness_keys[k]);
    if (it == head.end() || !it->is_number()) {
      return Status::corruption(fmt::format("{}: \"{}\" missing or not a number", path, thickness_keys[k]));
    }
    thickness[k] = it->get<double>();
  }
  auto graph = create(std::move(reader.rooms()), std::move(reader.portals()), thickness[0], thickness[1]);
  if (!graph) return Status::corruption(fmt::format("{}: {}", path, graph.status().message()));
  return graph;
}

// --- the section ------------------------------------------------------------------------------

std::vector<uint8_t> PortalGraph::serialize() const {
  std::vector<uint8_t> payload;
  GeometryWriter w(payload);
  w.reserve(kCountsBytes + kRoomBytes * rooms_.size() + kPortalBytes * portals_.size());
  w.f64(wall_);
  w.f64(slab_);
  w.u64(rooms_.size());
  w.u64(portals_.size());
  for (const Aabb& r : rooms_) w.box(r);
  for (const Portal& p : portals_) {
    w.u32(p.rooms[0]);
    w.u32(p.rooms[1]);
    for (const Vec3& v : p.polygon) w.vec3(v);
    w.box(p.opening);
  }
  return store::frame_section(kMagic, kVersion, payload);
}

Result<PortalGraph> PortalGraph::deserialize(std::span<const uint8_t> bytes, const std::string& what) {
  const auto corrupt = [&](const std::string& why) { return Status::corruption(fmt::format("{}: {}", what, why)); };
  auto section = store::unframe_section(bytes, kMagic, kVersion, what);
  if (!section) return section.status();
  GeometryReader r(section->payload);
  const double wall = r.f64(), slab = r.f64();
  const uint64_t room_count = r.u64(), portal_count = r.u64();
  if (!r.ok()) return corrupt("truncated counts");
  const uint64_t body = r.remaining();
  if (room_count > body / kRoomBytes || portal_count > (body - room_count * kRoomBytes) / kPortalBytes ||
      room_count * kRoomBytes + portal_count * kPortalBytes != body) {
    return corrupt(fmt::format("{} rooms and {} portals do not fill {} bytes", room_count, portal_count, body));
  }
  std::vector<Aabb> rooms(room_count);
  for (Aabb& room : rooms) room = r.box();
  std::vector<Portal> portals(portal_count);
  for (Portal& q : portals) {
    q.rooms[0] = r.u32();
    q.rooms[1] = r.u32();
    for (Vec3& corner : q.polygon) corner = r.vec3();
    q.opening = r.box();
  }
  auto graph = create(std::move(rooms), std::move(portals), wall, slab);
  if (!graph) return corrupt(graph.status().message());
  return graph;
}

// --- queries ----------------------------------------------------------------------------------

std::vector<uint32_t> PortalGraph::rooms_at(const Vec3& p) const {
  std::vector<uint32_t> found;
  if (locator_.first.empty() || !finite(p)) return found;
  size_t cell = 0;
  for (int a = 2; a >= 0; --a) {
    const double t = std::floor((p[a] - locator_.origin[a]) / locator_.cell[a]);
    if (t < 0.0 || t > double(locator_.dims[a])) return found;  // outside every box
    cell = cell * size_t(locator_.dims[a]) + size_t(std::min(t, double(locator_.dims[a] - 1)));
  }
  const auto room_items = static_cast<uint32_t>(rooms_.size());
  for (uint32_t k = locator_.first[cell]; k < locator_.first[cell + 1]; ++k) {
    const uint32_t item = locator_.items[k];
    if (item < room_items) {
      if (room_region(item).contains(p)) found.push_back(item);
    } else if (doorway(item - room_items).contains(p)) {
      const Portal& q = portals_[item - room_items];
      found.insert(found.end(), q.rooms.begin(), q.rooms.end());
    }
  }
  std::sort(found.begin(), found.end());
  found.erase(std::unique(found.begin(), found.end()), found.end());
  return found;
}

PortalVisibility PortalGraph::traverse(const View& view) const {
  PortalVisibility out;
  if (view.width <= 0 || view.height <= 0) return out;
  const std::vector<uint32_t> eye_rooms = rooms_at(view.eye);
  if (eye_rooms.empty()) return out;
  out.located = true;

  const Projector projector(view);
  std::unordered_map<uint32_t, std::vector<uint32_t>> visits_of;  // room -> its visits
  std::vector<uint32_t> passed;                                   // portals passed, once each
  std::unordered_set<uint32_t> passed_set;

  // Adds a visit unless an earlier visit of the room already covers its rectangle.
  auto offer = [&](uint32_t room, uint32_t via, int depth, Rect r) {
    if (r.empty()) return;
    std::vector<uint32_t>& earlier = visits_of[room];
    for (uint32_t v : earlier) {
      if (rect_of(out.visits[v]).contains(r)) return;
    }
    if (earlier.size() >= kVisitsBeforeWidening) {
      // Each further visit covers every earlier one, so each is strictly larger than the last.
      for (uint32_t v : earlier) r = r.hull(rect_of(out.visits[v]));
    }
    earlier.push_back(static_cast<uint32_t>(out.visits.size()));
    out.visits.push_back({room, via, depth, r.x0, r.y0, r.x1, r.y1});
  };

  const Rect screen{0, 0, view.width, view.height};
  for (uint32_t room : eye_rooms) offer(room, PortalVisit::kNoPortal, 0, screen);
  // Breadth first: out.visits is the queue.
  for (size_t i = 0; i < out.visits.size(); ++i) {
    const PortalVisit visit = out.visits[i];
    const Rect current = rect_of(visit);
    for (uint32_t portal : room_portals(visit.room)) {
      ++out.portals_tested;
      const bool standing_in = doorway(portal).contains(view.eye);
      if (!standing_in && !faces(portal, visit.room, view.eye)) continue;
      const Rect r = standing_in ? current : projector.narrow(portals_[portal].polygon, current);
      if (r.empty()) continue;
      ++out.portals_passed;
      if (passed_set.insert(portal).second) passed.push_back(portal);
      const auto& rooms = portals_[portal].rooms;
      offer(rooms[0] == visit.room ? rooms[1] : rooms[0], portal, visit.depth + 1, r);
    }
  }

  std::unordered_set<uint32_t> listed;
  for (const PortalVisit& v : out.visits) {
    if (listed.insert(v.room).second) out.regions.push_back(room_region(v.room));
  }
  for (uint32_t portal : passed) out.regions.push_back(portals_[portal].opening);
  return out;
}

}  // namespace frontier
