// frontier-build and the model store: round trips (raw exact, Draco within the lattice bound,
// rendering the store equals rendering the scene), no cracks between cells, corruption and
// truncation detected, a killed build leaves no store, peak memory within the budget, and the
// frontier-store tool.
#include "preprocess/build.h"
#include "src/io/load_scene.h"
#include "src/paging/store_model.h"
#include "src/walk/collision_grid.h"
#include "store/page_file.h"
#include "store/store_file.h"
#include "tests/engine_util.h"
#include "tests/process_util.h"
#include "tests/test_files.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <set>
#include <thread>

namespace frontier {
namespace {

namespace fs = std::filesystem;
using proc::run_binary;

const fs::path& scratch() { return testing::scratch_dir("frontier_build"); }
using testing::spd;

using frontier::proc::gen_binary;

// A generated building of about `triangles` triangles (cached per size within the run).
std::string building(uint64_t triangles) {
  const fs::path path = scratch() / ("building_" + std::to_string(triangles) + ".ply");
  if (!fs::exists(path)) {
    const auto r = run_binary(gen_binary(),
                              {"building", "--triangles", std::to_string(triangles), "-o", path.string(), "--quiet"},
                              scratch());
    EXPECT_EQ(r.exit_code, 0) << r.err;
    // Without its sidecar the building is not walkable: these tests ask for the grid explicitly.
    fs::remove(fs::path(path).replace_extension(".json"));
  }
  return path.string();
}

BuildOptions options_for(std::vector<std::string> inputs, const std::string& out, CellCodec codec) {
  BuildOptions o;
  o.inputs = std::move(inputs);
  o.output = out;
  o.codec = codec;
  o.quiet = true;
  o.threads = 2;
  o.cell_prims = 64;
  return o;
}

// A closed icosphere (radius r, `levels` subdivisions) as an ASCII OFF file.
std::string icosphere(int levels, double r, const Vec3& centre) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Vec3> v = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                         {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  std::vector<std::array<uint32_t, 3>> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                            {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                            {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                            {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (Vec3& p : v) p = glm::normalize(p);
  for (int l = 0; l < levels; ++l) {
    std::map<std::pair<uint32_t, uint32_t>, uint32_t> mid;
    auto midpoint = [&](uint32_t a, uint32_t b) {
      const auto key = std::minmax(a, b);
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      v.push_back(glm::normalize(v[a] + v[b]));
      return mid[key] = static_cast<uint32_t>(v.size() - 1);
    };
    std::vector<std::array<uint32_t, 3>> next;
    for (const auto& tri : f) {
      const uint32_t a = midpoint(tri[0], tri[1]), b = midpoint(tri[1], tri[2]), c = midpoint(tri[2], tri[0]);
      next.push_back({tri[0], a, c});
      next.push_back({tri[1], b, a});
      next.push_back({tri[2], c, b});
      next.push_back({a, b, c});
    }
    f = std::move(next);
  }
  const fs::path path = scratch() / ("icosphere_" + std::to_string(levels) + ".off");
  std::ofstream out(path);
  out.precision(17);
  out << "OFF\n" << v.size() << " " << f.size() << " 0\n";
  for (const Vec3& p : v) out << centre.x + r * p.x << " " << centre.y + r * p.y << " " << centre.z + r * p.z << "\n";
  for (const auto& tri : f) out << "3 " << tri[0] << " " << tri[1] << " " << tri[2] << "\n";
  return path.string();
}

std::string geometry_key(const Scene& s, uint32_t i) {
  const PrimRef& p = s.prims[i];
  std::ostringstream k;
  k.precision(17);
  k << int(p.kind) << ":" << p.source << ":" << p.material << ":";
  const Aabb b = s.prim_bounds(i);
  k << b.lo.x << "," << b.lo.y << "," << b.lo.z << "," << b.hi.x << "," << b.hi.y << "," << b.hi.z;
  if (p.kind == PrimKind::Triangle) {
    const Triangle& t = s.triangles[p.index];
    k << "|" << t.v0.x << "," << t.v0.y << "," << t.v0.z << "," << t.v1.x << "," << t.v1.y << "," << t.v1.z << ","
      << t.v2.x << "," << t.v2.y << "," << t.v2.z;
  }
  return k.str();
}

View view_of(const Scene& scene, int size) {
  const Camera cam = scene.camera ? *scene.camera : automatic_camera(scene.bounds());
  return View(cam, size, size);
}

// --- round trips ------------------------------------------------------------------------------

// The raw codec stores every primitive exactly; the store renders the same ids as the scene.
// part_primitives forces the out-of-core path (several parts split on disk).
TEST(BuildStore, RawRoundTripIsExactAndRendersTheSameIds) {
  for (const char* name : {"rings", "tree", "shells"}) {
    SCOPED_TRACE(name);
    Scene scene;
    ASSERT_TRUE(load_scene(spd(name), scene).is_ok());
    const std::string out = (scratch() / (std::string(name) + "_raw.frontier")).string();
    BuildOptions o = options_for({spd(name)}, out, CellCodec::Raw);
    o.part_primitives = scene.size() / 5 + 100;
    auto report = build_store(o);
    ASSERT_TRUE(report.is_ok()) << report.status().to_string();
    EXPECT_GT(report->parts, 3u) << "the out-of-core path was not taken";
    EXPECT_EQ(report->primitives, scene.size());

    auto model = StoreModel::open(out);
    ASSERT_TRUE(model.is_ok()) << model.status().to_string();
    Scene stored;
    KdTree stored_tree;
    ASSERT_TRUE((*model)->load_all(stored, stored_tree).is_ok());
    EXPECT_EQ(stored.size(), (*model)->info().references);
    EXPECT_GE(stored.size(), scene.size());

    // Every stored primitive is bit-identical to an input primitive, and every input primitive
    // is stored in at least one cell.
    std::multiset<std::string> input;
    for (uint32_t i = 0; i < scene.size(); ++i) input.insert(geometry_key(scene, i));
    std::set<std::string> seen;
    for (uint32_t i = 0; i < stored.size(); ++i) {
      const std::string k = geometry_key(stored, i);
      ASSERT_TRUE(input.count(k) > 0) << "stored primitive " << i << " is not an input primitive: " << k;
      seen.insert(k);
    }
    EXPECT_EQ(seen.size(), std::set<std::string>(input.begin(), input.end()).size());

    // Same ids as the in-memory scene, pixel for pixel, up to ties.
    const KdTree tree = KdTree::build(scene);
    const View view = view_of(scene, 129);
    std::vector<uint32_t> reference;
    std::vector<uint8_t> tie;
    testing::brute_reference(scene, view, reference, tie);
    for (Method m : {Method::RayWalk, Method::Frustum}) {
      const auto ids = testing::render_ids(stored, stored_tree, view, m);
      const auto cmp = testing::compare_ids(reference, tie, ids, view.width);
      EXPECT_EQ(cmp.mismatches, 0u) << cmp.first_mismatch;
    }
  }
}

// Draco: every decoded triangle is an input triangle moved by at most half a lattice step per
// axis, and keeps its source and material.
TEST(BuildStore, DracoRoundTripWithinLatticeBound) {
  const std::string in = building(30000);
  Scene scene;
  ASSERT_TRUE(load_scene(in, scene).is_ok());
  const std::string out = (scratch() / "building_draco.frontier").string();
  BuildOptions o = options_for({in}, out, CellCodec::Draco);
  o.quant_bits = 14;
  o.part_primitives = scene.size() / 3;
  auto report = build_store(o);
  ASSERT_TRUE(report.is_ok()) << report.status().to_string();
  auto model = StoreModel::open(out);
  ASSERT_TRUE(model.is_ok()) << model.status().to_string();
  const Lattice& lattice = (*model)->info().lattice;
  EXPECT_EQ(lattice.bits, 14);
  Scene stored;
  std::vector<std::vector<uint32_t>> cells;
  ASSERT_TRUE((*model)->load_scene(stored, cells).is_ok());

  std::map<uint32_t, std::vector<uint32_t>> by_source;
  for (uint32_t i = 0; i < scene.size(); ++i) by_source[scene.prims[i].source].push_back(i);
  const double bound = lattice.max_error() * (1.0 + 1e-9);
  auto close = [&](const Vec3& a, const Vec3& b) {
    return std::abs(a.x - b.x) <= bound && std::abs(a.y - b.y) <= bound && std::abs(a.z - b.z) <= bound;
  };
  std::set<uint32_t> sources_seen;
  for (uint32_t i = 0; i < stored.size(); ++i) {
    const PrimRef& p = stored.prims[i];
    ASSERT_EQ(p.kind, PrimKind::Triangle);
    const Triangle& t = stored.triangles[p.index];
    bool found = false;
    for (const uint32_t j : by_source[p.source]) {
      const Triangle& u = scene.triangles[scene.prims[j].index];
      const Vec3 tv[3] = {t.v0, t.v1, t.v2}, uv[3] = {u.v0, u.v1, u.v2};
      for (int rot = 0; rot < 3 && !found; ++rot) {
        found = close(tv[0], uv[rot]) && close(tv[1], uv[(rot + 1) % 3]) && close(tv[2], uv[(rot + 2) % 3]) &&
                scene.prims[j].material == p.material;
      }
      if (found) break;
    }
    ASSERT_TRUE(found) << "decoded triangle " << i << " (source " << p.source << ") matches no input triangle";
    sources_seen.insert(p.source);
  }
  // Only triangles that lost their area on the lattice may be missing.
  std::set<uint32_t> all;
  for (const auto& [s, list] : by_source) all.insert(s);
  EXPECT_GE(sources_seen.size() + (*model)->info().degenerate_dropped, all.size());
  EXPECT_LT(all.size() - sources_seen.size(), all.size() / 100 + 1);
}

// A closed mesh spread over many cells shows no background pixel inside its silhouette from
// 100 directions, at 12 and at 16 bits: shared vertices decode identically in every cell.
TEST(BuildStore, NoCracksBetweenCells) {
  const double r = 1.0;
  const Vec3 centre(1234.5, -987.25, 42.0);  // off the origin, so the lattice is not trivially aligned
  const std::string in = icosphere(5, r, centre);
  for (const int bits : {12, 16}) {
    SCOPED_TRACE(bits);
    const std::string out = (scratch() / ("sphere_" + std::to_string(bits) + ".frontier")).string();
    BuildOptions o = options_for({in}, out, CellCodec::Draco);
    o.quant_bits = bits;
    o.cell_prims = 128;
    auto report = build_store(o);
    ASSERT_TRUE(report.is_ok()) << report.status().to_string();
    auto model = StoreModel::open(out);
    ASSERT_TRUE(model.is_ok());
    size_t pages = 0;
    for (const StoreCell& c : (*model)->cells()) pages += c.page != StoreCell::kNoPage;
    ASSERT_GE(pages, 64u) << "the mesh should be spread over at least 64 cells";
    Scene stored;
    KdTree tree;
    ASSERT_TRUE((*model)->load_all(stored, tree).is_ok());
    // Inside this radius every ray must hit: the inscribed radius of the icosphere (edge
    // midpoints of its largest triangle sit at about r cos(half the edge angle)) less the lattice error.
    const double inner = r * 0.9995 - 2.0 * std::sqrt(3.0) * (*model)->info().lattice.max_error();
    size_t cracks = 0, inside = 0;
    const double golden = M_PI * (3.0 - std::sqrt(5.0));
    for (int d = 0; d < 100; ++d) {
      const double z = 1.0 - 2.0 * (d + 0.5) / 100.0, rho = std::sqrt(1.0 - z * z);
      const Vec3 dir(rho * std::cos(golden * d), rho * std::sin(golden * d), z);
      Camera cam;
      cam.eye = centre + 3.2 * r * dir;
      cam.look_at = centre;
      cam.up = std::abs(dir.z) > 0.9 ? Vec3(1, 0, 0) : Vec3(0, 0, 1);
      cam.vfov_deg = 45.0;
      const View view(cam, 48, 48);
      const auto ids = testing::render_ids(stored, tree, view, Method::Frustum);
      for (int y = 0; y < view.height; ++y) {
        for (int x = 0; x < view.width; ++x) {
          const Ray ray = view.ray(x, y);
          const Vec3 to_centre = centre - ray.origin;
          const double along = glm::dot(to_centre, ray.dir);
          const double miss = glm::length(to_centre - along * ray.dir);
          if (miss >= inner) continue;
          ++inside;
          if (ids[size_t(y) * 48 + size_t(x)] == kNoPrim) ++cracks;
        }
      }
    }
    EXPECT_GT(inside, 100000u);
    EXPECT_EQ(cracks, 0u) << "background pixels inside the silhouette";
  }
}

// Several inputs go into one store: ids continue across files, materials are concatenated.
TEST(BuildStore, SeveralInputsIntoOneStore) {
  Scene a, b;
  ASSERT_TRUE(load_scene(spd("rings"), a).is_ok());
  ASSERT_TRUE(load_scene(spd("shells"), b).is_ok());
  const std::string out = (scratch() / "two.frontier").string();
  auto report = build_store(options_for({spd("rings"), spd("shells")}, out, CellCodec::Raw));
  ASSERT_TRUE(report.is_ok()) << report.status().to_string();
  EXPECT_EQ(report->input_primitives, uint64_t{a.input_primitives} + b.input_primitives);
  EXPECT_EQ(report->primitives, a.size() + b.size());
  auto model = StoreModel::open(out);
  ASSERT_TRUE(model.is_ok());
  EXPECT_EQ((*model)->info().materials.size(), a.materials.size() + b.materials.size());
  EXPECT_EQ((*model)->info().inputs.size(), 2u);
  Scene stored;
  std::vector<std::vector<uint32_t>> cells;
  ASSERT_TRUE((*model)->load_scene(stored, cells).is_ok());
  uint32_t max_source = 0;
  for (const PrimRef& p : stored.prims) max_source = std::max(max_source, p.source);
  EXPECT_GE(max_source, a.input_primitives);
  EXPECT_LT(max_source, a.input_primitives + b.input_primitives);
}

// --- damaged stores ----------------------------------------------------------------------------

// Reads everything a viewer would: open, every checksum, the model sections, every cell.
Status read_everything(const std::string& path) {
  store::PosixFileSystem fs;
  auto reader = store::StoreReader::open(fs, path);
  if (!reader) return reader.status();
  if (Status s = (*reader)->verify(); !s) return s;
  auto model = StoreModel::open(std::move(*reader));
  if (!model) return model.status();
  Scene cell;
  for (uint32_t c = 0; c < (*model)->cells().size(); ++c) {
    if (Status s = (*model)->read_cell(c, cell); !s) return s;
  }
  return Status::ok();
}

std::vector<uint8_t> read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}
void write_file(const std::string& path, const std::vector<uint8_t>& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

// Binary PLY inputs are parsed again by the first partition pass instead of spilled first: the
// store must be the same file byte for byte, from one input and from two (material bases and
// sources continue across inputs), with Draco and raw, out of core.
TEST(BuildStore, ReparsedBinaryPlyGivesTheSameStoreAsTheSpill) {
  const std::string one = building(20000), two = building(12000);
  for (CellCodec codec : {CellCodec::Draco, CellCodec::Raw}) {
    for (const std::vector<std::string>& inputs : {std::vector<std::string>{one}, std::vector<std::string>{one, two}}) {
      std::vector<uint8_t> stores[2];
      BuildReport reports[2];
      for (int reparse = 0; reparse < 2; ++reparse) {
        const std::string out = (scratch() / ("reparse_" + std::to_string(reparse) + ".frontier")).string();
        BuildOptions o = options_for(inputs, out, codec);
        o.part_primitives = 9000;  // the root part is split on disk
        o.reparse_binary_ply = reparse == 1;
        auto report = build_store(o);
        ASSERT_TRUE(report.is_ok()) << report.status().to_string();
        reports[reparse] = *report;
        stores[reparse] = read_file(out);
      }
      EXPECT_GT(reports[1].parts, 2u);
      // The reparse writes no ingest file: only the parts.
      EXPECT_LT(reports[1].spill_bytes, reports[0].spill_bytes);
      EXPECT_EQ(reports[0].primitives, reports[1].primitives);
      EXPECT_EQ(reports[0].degenerate_dropped, reports[1].degenerate_dropped);
      EXPECT_TRUE(stores[0] == stores[1]) << inputs.size() << " input(s): the stores differ";
    }
  }
}

TEST(BuildStore, EverySampledByteFlipIsReportedAsCorruption) {
  const std::string out = (scratch() / "flip.frontier").string();
  auto report = build_store(options_for({spd("shells")}, out, CellCodec::Draco));
  ASSERT_TRUE(report.is_ok()) << report.status().to_string();
  ASSERT_TRUE(read_everything(out).is_ok());
  const std::vector<uint8_t> good = read_file(out);
  store::PosixFileSystem fs;
  auto reader = store::StoreReader::open(fs, out);
  ASSERT_TRUE(reader.is_ok());
  const uint64_t dir = (*reader)->sections().empty() ? 0 : (*reader)->section(kCellsSection)->offset;
  // 700 positions among the pages and sections, 200 in the directory and the sections after
  // the cells, 100 in the footer and header.
  std::mt19937_64 rng(7);
  std::vector<size_t> positions;
  for (int i = 0; i < 700; ++i) positions.push_back(std::uniform_int_distribution<size_t>(24, dir - 1)(rng));
  for (int i = 0; i < 200; ++i) positions.push_back(std::uniform_int_distribution<size_t>(dir, good.size() - 41)(rng));
  for (int i = 0; i < 80; ++i) positions.push_back(good.size() - 40 + size_t(i % 40));
  for (int i = 0; i < 20; ++i) positions.push_back(size_t(i % 24));
  const std::string bad = (scratch() / "flip_bad.frontier").string();
  size_t undetected = 0;
  std::string first;
  for (const size_t pos : positions) {
    std::vector<uint8_t> bytes = good;
    bytes[pos] ^= static_cast<uint8_t>(1u << (pos % 8));
    write_file(bad, bytes);
    const Status s = read_everything(bad);
    if (s.is_ok() || s.code() != Status::Code::Corruption) {
      if (first.empty()) first = "byte " + std::to_string(pos) + ": " + s.to_string();
      ++undetected;
    }
  }
  EXPECT_EQ(undetected, 0u) << first;
}

TEST(BuildStore, TruncatedStoresAndForeignFilesGetClearErrors) {
  const std::string out = (scratch() / "trunc.frontier").string();
  ASSERT_TRUE(build_store(options_for({spd("rings")}, out, CellCodec::Draco)).is_ok());
  const std::vector<uint8_t> good = read_file(out);
  const std::string bad = (scratch() / "trunc_bad.frontier").string();
  for (size_t len : {size_t(0), size_t(10), size_t(63), good.size() / 2, good.size() - 41, good.size() - 1}) {
    write_file(bad, std::vector<uint8_t>(good.begin(), good.begin() + static_cast<ptrdiff_t>(len)));
    auto model = StoreModel::open(bad);
    ASSERT_FALSE(model.is_ok()) << "truncated to " << len;
    EXPECT_EQ(model.status().code(), Status::Code::Corruption);
    EXPECT_NE(model.status().message().find(bad), std::string::npos) << model.status().message();
  }
  // A model file is not a store.
  auto foreign = StoreModel::open(spd("rings"));
  ASSERT_FALSE(foreign.is_ok());
  EXPECT_NE(foreign.status().message().find("rings.nff"), std::string::npos);
}

// --- the frontier-build and frontier-store commands ------------------------------------------

TEST(BuildCommand, KilledBuildLeavesNoStoreAndKeepsTheOldOne) {
  const std::string in = building(400000);
  const fs::path out = scratch() / "killed.frontier";
  std::mt19937_64 rng(11);
  for (int attempt = 0; attempt < 6; ++attempt) {
    const bool had_old = attempt % 2 == 1;
    fs::remove(out);  // an attempt that finished before the kill left its store
    if (had_old) write_file(out.string(), {'o', 'l', 'd'});
    const auto so = scratch() / "kill_out", se = scratch() / "kill_err";
    const pid_t pid = proc::spawn(FRONTIER_BUILD_PATH, {in, "-o", out.string(), "--quiet", "--memory", "32M"}, so, se);
    std::this_thread::sleep_for(std::chrono::milliseconds(std::uniform_int_distribution<int>(20, 900)(rng)));
    ::kill(pid, SIGKILL);
    const auto r = proc::finish(pid, so, se);
    if (r.exit_code == 0) continue;  // finished before the kill: nothing to check
    const std::vector<uint8_t> old_bytes = {'o', 'l', 'd'};
    if (fs::exists(out) && read_file(out.string()) != old_bytes) {
      // Killed after the rename (the build was done, only exiting): a complete store is fine.
      EXPECT_TRUE(read_everything(out.string()).is_ok()) << "attempt " << attempt << ": a killed build left a "
                                                          << "store that does not read";
    } else if (had_old) {
      EXPECT_EQ(read_file(out.string()), old_bytes) << "attempt " << attempt;
    } else {
      EXPECT_FALSE(fs::exists(out)) << "attempt " << attempt << ": a killed build left a store";
    }
    fs::remove(out);
  }
  // The next build succeeds and removes what killed builds left behind.
  const auto r = run_binary(FRONTIER_BUILD_PATH, {in, "-o", out.string(), "--quiet"}, scratch());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(read_everything(out.string()).is_ok());
  for (const auto& e : fs::directory_iterator(scratch())) {
    EXPECT_EQ(e.path().filename().string().find(".killed.frontier.build-"), std::string::npos) << e.path();
  }
}

TEST(BuildCommand, PeakMemoryStaysWithinTheBudget) {
  // A model file at least 4x the budget: 16 MiB of memory for a building of 64+ MiB of PLY.
  const std::string in = building(3500000);
  const uint64_t budget = uint64_t{16} << 20;
  ASSERT_GE(fs::file_size(in), 4 * budget);
  const fs::path out = scratch() / "memory.frontier";
  const auto r = run_binary(FRONTIER_BUILD_PATH, {in, "-o", out.string(), "--memory", "16M", "--threads", "2"}, scratch());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const double peak_mib = static_cast<double>(r.max_rss_kb) / 1024.0;
  std::printf("peak RSS %.1f MiB for a %.1f MiB model with --memory 16M\n%s", peak_mib,
              static_cast<double>(fs::file_size(in)) / (1 << 20), r.err.c_str());
  EXPECT_LT(peak_mib, 16.0 + 128.0);
  EXPECT_TRUE(read_everything(out.string()).is_ok());
  fs::remove(out);
}

TEST(BuildCommand, WalkableBuildKeepsTheGridOutOfMemory) {
  // The collision grid of this model, at 5 cm, has more voxels than the budget and the allowance
  // could hold as bare floats; the build spills it brick by brick and stays within both.
  const std::string in = building(300000);
  const fs::path out = scratch() / "walk_memory.frontier";
  const auto r = run_binary(FRONTIER_BUILD_PATH, {in, "-o", out.string(), "--memory", "16M", "--threads", "2",
                                                  "--walkable", "--sdf-voxel", "0.05"},
                            scratch());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  auto model = StoreModel::open(out.string());
  ASSERT_TRUE(model.is_ok()) << model.status().to_string();
  auto grid = open_collision_grid((*model)->reader());
  ASSERT_TRUE(grid.is_ok()) << grid.status().to_string();
  const double grid_mib = 4.0 * static_cast<double>((*grid)->active_voxels()) / (1 << 20);
  const double peak_mib = static_cast<double>(r.max_rss_kb) / 1024.0;
  std::printf("peak RSS %.1f MiB with --memory 16M; the grid's %llu active voxels are %.1f MiB as floats\n%s",
              peak_mib, static_cast<unsigned long long>((*grid)->active_voxels()), grid_mib, r.err.c_str());
  EXPECT_GT(grid_mib, 16.0 + 128.0);
  EXPECT_LT(peak_mib, 16.0 + 128.0);
  const auto verify = run_binary(FRONTIER_STORE_PATH, {"verify", "--quiet", out.string()}, scratch());
  EXPECT_EQ(verify.exit_code, 0) << verify.err;
  fs::remove(out);
}

TEST(BuildCommand, BadInputAndOptionsFailCleanly) {
  const fs::path bad = scratch() / "bad.obj";
  {
    std::ofstream f(bad);
    f << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nv 1 nonsense 2\n";
  }
  const fs::path out = scratch() / "bad.frontier";
  auto r = run_binary(FRONTIER_BUILD_PATH, {bad.string(), "-o", out.string(), "--quiet"}, scratch());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("bad.obj"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("line 5"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(out));
  EXPECT_FALSE(fs::exists(out.string() + ".tmp"));
  r = run_binary(FRONTIER_BUILD_PATH, {spd("rings"), "-o", out.string(), "--quant-bits", "40"}, scratch());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--quant-bits"), std::string::npos) << r.err;
  r = run_binary(FRONTIER_BUILD_PATH, {spd("rings"), "-o", out.string(), "--memory", "lots"}, scratch());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_FALSE(fs::exists(out));
}

// An error deep in the input, after the reader thread has handed over many batches: the build
// still fails with the file and line, and leaves nothing behind.
TEST(BuildStore, MalformedLineAfterManyBatchesFailsCleanly) {
  const fs::path bad = scratch() / "late_bad.obj";
  constexpr int kQuads = 20000;  // 40000 triangles: ten batches before the bad line
  {
    std::ofstream f(bad);
    for (int i = 0; i < kQuads; ++i) {
      f << "v " << i << " 0 0\nv " << i + 1 << " 0 0\nv " << i + 1 << " 1 0\nv " << i << " 1 0\n";
      f << "f " << 4 * i + 1 << " " << 4 * i + 2 << " " << 4 * i + 3 << " " << 4 * i + 4 << "\n";
    }
    f << "f 1 2 nonsense\n";
  }
  const int bad_line = 5 * kQuads + 1;
  for (const CellCodec codec : {CellCodec::Draco, CellCodec::Raw}) {
    const std::string out = (scratch() / "late_bad.frontier").string();
    auto report = build_store(options_for({bad.string()}, out, codec));
    ASSERT_FALSE(report.is_ok());
    const std::string message = report.status().message();
    EXPECT_NE(message.find("late_bad.obj"), std::string::npos) << message;
    EXPECT_NE(message.find("line " + std::to_string(bad_line)), std::string::npos) << message;
    EXPECT_FALSE(fs::exists(out));
    EXPECT_FALSE(fs::exists(out + ".tmp"));
    for (const auto& e : fs::directory_iterator(scratch())) {
      EXPECT_EQ(e.path().filename().string().find(".late_bad.frontier.build-"), std::string::npos) << e.path();
    }
  }
}

TEST(StoreCommand, InfoAndVerify) {
  const fs::path out = scratch() / "tool.frontier";
  ASSERT_TRUE(build_store(options_for({spd("tree")}, out.string(), CellCodec::Draco)).is_ok());
  auto r = run_binary(FRONTIER_STORE_PATH, {"info", out.string()}, scratch());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  for (const char* word : {"primitives", "cells", "depth", "bytes/tri", "draco", "lattice", "cell sizes"}) {
    EXPECT_NE(r.out.find(word), std::string::npos) << word << " missing from:\n" << r.out;
  }
  r = run_binary(FRONTIER_STORE_PATH, {"verify", out.string()}, scratch());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("ok"), std::string::npos);

  // Damage one page: verify names it and exits 1.
  store::PosixFileSystem fs;
  auto reader = store::StoreReader::open(fs, out.string());
  ASSERT_TRUE(reader.is_ok());
  ASSERT_GT((*reader)->page_count(), 3u);
  const store::Handle h = (*reader)->page_handle(3);
  std::vector<uint8_t> bytes = read_file(out.string());
  bytes[h.offset + h.size / 2] ^= 0x40;
  write_file(out.string(), bytes);
  r = run_binary(FRONTIER_STORE_PATH, {"verify", out.string()}, scratch());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("page at offset " + std::to_string(h.offset)), std::string::npos) << r.err;
}

TEST(BuildStore, WalkableAddsADistanceGrid) {
  const std::string in = building(30000);
  const std::string out = (scratch() / "walk.frontier").string();
  BuildOptions o = options_for({in}, out, CellCodec::Draco);
  o.walkable = true;
  o.part_primitives = 8000;
  auto report = build_store(o);
  ASSERT_TRUE(report.is_ok()) << report.status().to_string();
  auto model = StoreModel::open(out);
  ASSERT_TRUE(model.is_ok());
  EXPECT_TRUE((*model)->info().walkable);
  auto grid = open_collision_grid((*model)->reader());
  ASSERT_TRUE(grid.is_ok()) << grid.status().to_string();
  // Points on the model's geometry are at distance ~0; the grid is not empty.
  Scene scene;
  ASSERT_TRUE(load_scene(in, scene).is_ok());
  const double voxel = (*model)->info().sdf_voxel;
  int near = 0;
  for (uint32_t i = 0; i < scene.size(); i += scene.size() / 50) {
    const Triangle& t = scene.triangles[scene.prims[i].index];
    if ((*grid)->distance((t.v0 + t.v1 + t.v2) / 3.0) <= 1.5 * voxel) ++near;
  }
  EXPECT_GE(near, 48);
  // The grid is paged: nothing resident until queried, and the bricks are pages of their own.
  const std::vector<uint64_t> bricks = (*grid)->brick_pages();
  EXPECT_EQ(bricks.size(), (*grid)->counters().bricks);
  EXPECT_GE(bricks.size(), 2u);
  EXPECT_EQ(report->sdf_bricks, bricks.size());
  EXPECT_EQ((*model)->reader().page_count(), report->pages + bricks.size() + report->proxy_pages);
  // A flipped byte in a brick page: verify names the page; the grid reads that brick as solid.
  const store::Handle h = (*model)->reader().page_handle(bricks[1]);
  const store::Handle* handle = &h;
  std::vector<uint8_t> bytes = read_file(out);
  bytes[handle->offset + handle->size / 2] ^= 0x10;
  const std::string bad = (scratch() / "walk_bad.frontier").string();
  write_file(bad, bytes);
  const auto verify = run_binary(FRONTIER_STORE_PATH, {"verify", bad}, scratch());
  EXPECT_EQ(verify.exit_code, 1);
  EXPECT_NE(verify.err.find("offset " + std::to_string(handle->offset)), std::string::npos) << verify.err;
  auto bad_model = StoreModel::open(bad);
  ASSERT_TRUE(bad_model.is_ok());  // the brick is read only when a query reaches it
  auto bad_grid = open_collision_grid((*bad_model)->reader());
  ASSERT_TRUE(bad_grid.is_ok());
  const Status check = (*bad_grid)->check_all_bricks();
  EXPECT_EQ(check.code(), Status::Code::Corruption);
  EXPECT_NE(check.message().find("page " + std::to_string(bricks[1])), std::string::npos) << check.to_string();
  // A store without --walkable has no grid.
  auto plain = StoreModel::open((scratch() / "building_draco.frontier").string());
  if (plain) {
    EXPECT_FALSE((*plain)->reader().section(kSdfSection).has_value());
  }
}

}  // namespace
}  // namespace frontier
