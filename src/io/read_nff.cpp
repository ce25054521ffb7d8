// NFF reader (Eric Haines' Neutral File Format, as the SPD scenes use it).
//
// The file is read as a stream of tokens, not lines (a cone's 8 numbers may span lines), and
// the reader holds nothing but the current primitive. Camera, background, lights and
// materials go into the header as they appear; `f` appends a material that every following
// primitive uses. A primitive before any `f` gets a default material, pushed once.
// Unknown keywords are errors naming their line.
#include "src/io/read_formats.h"
#include "src/io/text_tokenizer.h"

#include <fmt/format.h>

#include <cmath>

namespace frontier {
namespace {

class NffReader final : public FormatReader {
 public:
  Status open(const std::string& path) { return tok_.open(path, {.hash_comments = true}); }

  uint64_t bytes_read() const override { return tok_.offset(); }
  uint64_t bytes_total() const override { return tok_.size(); }

 private:
  Status read_next(InputPrimitive& out, bool& end) override;
  Status read_sphere(InputPrimitive& out);
  Status read_cone(InputPrimitive& out);
  Status read_polygon(InputPrimitive& out, bool with_normals);
  Status read_light();
  Status read_material();
  Camera& camera() {
    if (!header_.camera) header_.camera.emplace();
    return *header_.camera;
  }
  void start_primitive(InputPrimitive& out, InputPrimitive::Kind kind) {
    if (header_.materials.empty()) header_.materials.emplace_back();  // no `f` yet
    out.kind = kind;
    out.material = static_cast<uint32_t>(header_.materials.size() - 1);
    out.vertices.clear();
    out.normals.clear();
  }

  TextTokenizer tok_;
};

Status NffReader::read_next(InputPrimitive& out, bool& end) {
  std::string_view kw;
  for (;;) {
    if (Status s = tok_.next_statement(kw, end); !s || end) return s;
    Status s;
    if (kw == "s") return read_sphere(out);
    if (kw == "c") return read_cone(out);
    if (kw == "p") return read_polygon(out, false);
    if (kw == "pp") return read_polygon(out, true);
    if (kw == "f") {
      s = read_material();
    } else if (kw == "l") {
      s = read_light();
    } else if (kw == "b") {
      s = tok_.next_vec3(header_.background, "background colour");
    } else if (kw == "v") {
      camera();
    } else if (kw == "from") {
      s = tok_.next_vec3(camera().eye, "eye position");
    } else if (kw == "at") {
      s = tok_.next_vec3(camera().look_at, "look-at point");
    } else if (kw == "up") {
      s = tok_.next_vec3(camera().up, "up vector");
    } else if (kw == "angle") {
      double a = 0.0;
      s = tok_.next_double(a, "field of view angle");
      if (s && !(a > 0.0 && a < 180.0)) s = tok_.error(fmt::format("field of view angle {} is not in (0, 180)", a));
      if (s) camera().vfov_deg = a;
    } else if (kw == "hither") {
      s = tok_.next_double(camera().near, "hither distance");
    } else if (kw == "resolution") {
      int64_t w = 0, h = 0;
      s = tok_.next_int(w, "resolution width");
      if (s) s = tok_.next_int(h, "resolution height");
      if (s && (w <= 0 || h <= 0 || w > (1 << 16) || h > (1 << 16))) {
        s = tok_.error(fmt::format("resolution {} x {} is out of range", w, h));
      }
      if (s) {
        camera().width = static_cast<int>(w);
        camera().height = static_cast<int>(h);
      }
    } else {
      return tok_.error(fmt::format("unknown keyword {}", quote_token(kw)));
    }
    if (!s) return s;
  }
}

Status NffReader::read_sphere(InputPrimitive& out) {
  start_primitive(out, InputPrimitive::Kind::Sphere);
  Status s = tok_.next_vec3(out.sphere.center, "sphere centre");
  if (s) s = tok_.next_double(out.sphere.radius, "sphere radius");
  if (s && out.sphere.radius < 0.0) s = tok_.error("sphere radius is negative");
  return s;
}

Status NffReader::read_cone(InputPrimitive& out) {
  start_primitive(out, InputPrimitive::Kind::Cone);
  Cone& c = out.cone;
  Status s = tok_.next_vec3(c.base, "cone base point");
  if (s) s = tok_.next_double(c.base_radius, "cone base radius");
  if (s) s = tok_.next_vec3(c.apex, "cone apex point");
  if (s) s = tok_.next_double(c.apex_radius, "cone apex radius");
  // Negative radii mark an inside-out cone in NFF; the surface is the same.
  c.base_radius = std::abs(c.base_radius);
  c.apex_radius = std::abs(c.apex_radius);
  return s;
}

Status NffReader::read_polygon(InputPrimitive& out, bool with_normals) {
  start_primitive(out, InputPrimitive::Kind::Polygon);
  const char* what = with_normals ? "patch" : "polygon";
  int64_t n = 0;
  Status s = tok_.next_int(n, fmt::format("{} vertex count", what));
  if (!s) return s;
  if (std::string bad = check_polygon_size(n, what); !bad.empty()) return tok_.error(bad);
  out.vertices.resize(static_cast<size_t>(n));
  if (with_normals) out.normals.resize(static_cast<size_t>(n));
  for (int64_t i = 0; i < n; ++i) {
    s = tok_.next_vec3(out.vertices[i], "vertex coordinate");
    if (s && with_normals) s = tok_.next_vec3(out.normals[i], "vertex normal");
    if (!s) return s;
  }
  return Status::ok();
}

Status NffReader::read_light() {
  PointLight light;
  Status s = tok_.next_vec3(light.position, "light position");
  if (!s) return s;
  // The colour is optional: it is there when the next token is a number, not a keyword.
  std::string_view t;
  double v = 0.0;
  bool finite = true;
  if (tok_.peek(t) && parse_double(t, v, finite)) {
    s = tok_.next_vec3(light.color, "light colour");
    if (!s) return s;
  }
  header_.lights.push_back(light);
  return Status::ok();
}

Status NffReader::read_material() {
  Material m;
  double v[5];
  Status s = tok_.next_vec3(m.color, "material colour");
  static constexpr const char* kNames[5] = {"Kd", "Ks", "Shine", "T", "index of refraction"};
  for (int k = 0; s && k < 5; ++k) s = tok_.next_double(v[k], kNames[k]);
  if (!s) return s;
  m.kd = v[0];
  m.ks = v[1];
  m.shine = v[2];
  m.transmittance = v[3];
  m.ior = v[4];
  header_.materials.push_back(m);
  return Status::ok();
}

}  // namespace

Result<std::unique_ptr<SceneReader>> open_nff_reader(const std::string& path) {
  return open_format_reader<NffReader>(path);
}

}  // namespace frontier
