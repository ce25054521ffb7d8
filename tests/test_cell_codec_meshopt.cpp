// The meshopt cell codec (src/codec/meshopt_codec.cpp): a terrain-like cell far from the origin
// and a mixed cell (sources, materials, normals, curved primitives) round-trip on the lattice,
// damaged pages give Corruption naming the cell and page, never a crash, and a whole store built
// with `frontier-build --codec meshopt` holds the same geometry and renders the same ids as the
// Draco store of the same model. The properties meshopt shares with Draco (shared seam
// vertices, lattice-degenerate triangles dropped, empty and single-triangle cells, normals) are
// the CellCodecOnLattice tests of test_cell_codec.cpp, which run both codecs.
#include "src/codec/cell_codec.h"
#include "src/codec/cell_tree.h"
#include "src/paging/store_model.h"
#include "store/store_file.h"
#include "tests/cell_codec_util.h"
#include "tests/engine_util.h"
#include "tests/process_util.h"
#include "tests/test_files.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <random>

namespace frontier {
namespace {

using namespace codec_test;
namespace fs = std::filesystem;

// An n x n height field (two triangles per square) around `at`, snapped to `lattice`, with
// sources in row order and a material per band of rows: what a terrain cell holds.
Scene terrain_cell(const Vec3& at, int n, const Lattice& lattice) {
  auto height = [&](int i, int j) { return 3.0 * std::sin(i * 0.37) * std::cos(j * 0.23) + 0.01 * ((i * 7 + j) % 5); };
  auto p = [&](int i, int j) { return lattice.snap(at + Vec3(i * 0.5, j * 0.5, height(i, j))); };
  Scene scene;
  uint32_t source = 500;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const uint32_t material = static_cast<uint32_t>(i / 8);
      scene.add_triangle({p(i, j), p(i + 1, j), p(i + 1, j + 1)}, source++, material);
      scene.add_triangle({p(i, j), p(i + 1, j + 1), p(i, j + 1)}, source++, material);
    }
  }
  return scene;
}

Lattice terrain_lattice(const Vec3& at, int n, int bits) {
  return Lattice::covering(Aabb(at - Vec3(1.0, 1.0, 5.0), at + Vec3(0.5 * n + 1.0, 0.5 * n + 1.0, 5.0)), bits);
}

TEST(CellCodecMeshopt, TerrainCellFarFromTheOriginRoundTripsOnTheLattice) {
  const Vec3 far(1e6, -1e6, 1e6);
  const Lattice lattice = terrain_lattice(far, 40, 16);
  const Scene cell = terrain_cell(far, 40, lattice);
  auto encoded = encode_on(CellCodec::Meshopt, cell, lattice);
  ASSERT_TRUE(encoded.is_ok()) << encoded.status().to_string();
  EXPECT_EQ(encoded->codec, CellCodec::Meshopt);
  Scene decoded;
  const Status s = decode_cell(encoded->payload, CellCodec::Meshopt, lattice, decoded);
  ASSERT_TRUE(s.is_ok()) << s.to_string();
  expect_identical(encoded->decoded, decoded);
  // Every triangle, bit for bit (the input is on the lattice), with its source and material.
  EXPECT_EQ(triangle_multiset(decoded), triangle_multiset(cell));
  ASSERT_EQ(decoded.size(), cell.size());
  // The page costs what the codec promises: well under raw's 72 bytes of corners.
  const double per_triangle = static_cast<double>(encoded->payload.size()) / static_cast<double>(cell.size());
  std::printf("[ info ] meshopt terrain cell: %.2f bytes/triangle\n", per_triangle);
  EXPECT_LT(per_triangle, 8.0);
  EXPECT_GT(per_triangle, 0.5);
}

TEST(CellCodecMeshopt, MixedCellKeepsSourcesMaterialsNormalsAndShapes) {
  const Vec3 far(-2e6, 3e6, 1e6);
  const Scene unsnapped = sphere_mesh(far, 4.0, 30, 16, nullptr);
  const Lattice lattice = lattice_for(unsnapped, 18, 5.0);
  Scene cell = sphere_mesh(far, 4.0, 30, 16, &lattice, true);
  add_other_primitives(cell, far, 9000);
  // Shapes between the triangles and one more triangle after them: primitive order is mixed.
  std::swap(cell.prims[5], cell.prims[cell.prims.size() - 2]);
  cell.prims[3].material = 77;
  const std::array<Vec3, 3> n = {Vec3(0, 0, 1), Vec3(0, 1, 0), Vec3(1, 0, 0)};
  cell.add_triangle({lattice.snap(far + Vec3(6, 0, 0)), lattice.snap(far + Vec3(7, 0, 0)),
                     lattice.snap(far + Vec3(6, 1, 0))}, 4000000000u, 12, &n);
  auto encoded = encode_on(CellCodec::Meshopt, cell, lattice);
  ASSERT_TRUE(encoded.is_ok()) << encoded.status().to_string();
  Scene decoded;
  ASSERT_TRUE(decode_cell(encoded->payload, CellCodec::Meshopt, lattice, decoded).is_ok());
  expect_identical(encoded->decoded, decoded);
  ASSERT_EQ(decoded.size(), cell.size());
  EXPECT_EQ(triangle_multiset(decoded), triangle_multiset(cell));

  // Each corner's normal travels with its corner (the index codec may rotate a triangle): the
  // decoded normal at a decoded corner is the input normal at that corner.
  std::map<std::tuple<uint32_t, Corner>, Vec3> input_normals;
  for (const PrimRef& p : cell.prims) {
    if (p.kind != PrimKind::Triangle) continue;
    const Triangle& t = cell.triangles[p.index];
    const Vec3 v[3] = {t.v0, t.v1, t.v2};
    for (int c = 0; c < 3; ++c) input_normals[{p.source, Corner{v[c].x, v[c].y, v[c].z}}] = cell.triangle_normals[p.index][c];
  }
  ASSERT_EQ(decoded.triangle_normals.size(), decoded.triangles.size());
  double worst = 1.0;
  for (const PrimRef& p : decoded.prims) {
    if (p.kind != PrimKind::Triangle) continue;
    const Triangle& t = decoded.triangles[p.index];
    const Vec3 v[3] = {t.v0, t.v1, t.v2};
    for (int c = 0; c < 3; ++c) {
      const auto it = input_normals.find({p.source, Corner{v[c].x, v[c].y, v[c].z}});
      ASSERT_NE(it, input_normals.end());
      worst = std::min(worst, glm::dot(glm::normalize(decoded.triangle_normals[p.index][c]), it->second));
    }
  }
  EXPECT_GT(worst, std::cos(0.5 * kPi / 180));  // 10-bit octahedral normals

  // The shapes come after the triangles, in input order, bit for bit.
  Scene shapes, decoded_shapes;
  for (uint32_t i = 0; i < cell.size(); ++i) {
    if (cell.prims[i].kind != PrimKind::Triangle) shapes.add_from(cell, i);
  }
  const size_t triangles = decoded.triangles.size();
  for (uint32_t i = 0; i < decoded.size(); ++i) {
    EXPECT_EQ(decoded.prims[i].kind == PrimKind::Triangle, i < triangles) << i;
    if (i >= triangles) decoded_shapes.add_from(decoded, i);
  }
  expect_identical(decoded_shapes, shapes);
}

TEST(CellCodecMeshopt, RejectsOffLatticeVerticesAndBadNormalBits) {
  const Lattice lattice = Lattice::covering(Aabb(Vec3(0), Vec3(10)), 16);
  Scene cell;
  const std::array<Vec3, 3> n = {Vec3(0, 0, 1), Vec3(0, 0, 1), Vec3(0, 0, 1)};
  cell.add_triangle({lattice.snap(Vec3(1)), lattice.snap(Vec3(2, 1, 1)), lattice.snap(Vec3(1, 2, 1))}, 1, 0, &n);
  cell.add_triangle({lattice.snap(Vec3(1)), Vec3(2.0000001, 1, 1), lattice.snap(Vec3(1, 2, 1))}, 2, 0, &n);
  auto encoded = encode_on(CellCodec::Meshopt, cell, lattice);
  ASSERT_FALSE(encoded.is_ok());
  EXPECT_EQ(encoded.status().code(), Code::InvalidArgument);
  EXPECT_NE(encoded.status().message().find("primitive 1"), std::string::npos) << encoded.status().message();

  cell.triangles.pop_back();
  cell.prims.pop_back();
  cell.triangle_normals.pop_back();
  CellCodecOptions options;
  options.codec = CellCodec::Meshopt;
  options.lattice = lattice;
  options.normal_bits = 17;  // meshoptimizer's octahedral filter stores at most 16 bits
  EXPECT_EQ(encode_cell(cell, options).status().code(), Code::InvalidArgument);
  options.normal_bits = 16;
  auto good = encode_cell(cell, options);
  ASSERT_TRUE(good.is_ok()) << good.status().to_string();
  Scene out;
  Lattice other = lattice;
  other.bits = 12;
  EXPECT_EQ(decode_cell(good->payload, CellCodec::Meshopt, other, out).code(), Code::Corruption);
  EXPECT_EQ(decode_cell(good->payload, CellCodec::Draco, lattice, out).code(), Code::Corruption);
}

TEST(CellCodecCorruption, DamagedMeshoptPagesNeverCrash) {
  for (bool normals : {false, true}) {
    SCOPED_TRACE(normals);
    const Scene unsnapped = sphere_mesh(Vec3(-4e6), 2.0, 24, 14, nullptr);
    const Lattice lattice = lattice_for(unsnapped, 16, 1.0);
    Scene cell = sphere_mesh(Vec3(-4e6), 2.0, 24, 14, &lattice, normals);
    add_other_primitives(cell, Vec3(-4e6), 3);
    auto encoded = encode_on(CellCodec::Meshopt, cell, lattice);
    ASSERT_TRUE(encoded.is_ok()) << encoded.status().to_string();
    check_damage(encoded->payload, CellCodec::Meshopt, lattice, 1500);
  }
}

// --- whole stores ----------------------------------------------------------------------------

const fs::path& scratch() { return testing::scratch_dir("frontier_meshopt"); }

// Builds `model` into `out` with `frontier-build --codec CODEC`, as a user does.
void build_with(const std::string& codec, const std::string& model, const std::string& out) {
  const auto r = proc::run_binary(FRONTIER_BUILD_PATH, {model, "-o", out, "--codec", codec, "--cell-prims", "64",
                                                        "--threads", "2", "--quiet"}, scratch());
  ASSERT_EQ(r.exit_code, 0) << r.err;
}

// The meshopt store decodes to the Draco store's
// primitives — the same multiset of (source, material, lattice triangle) and the same shapes —
// and renders the same ids, pixel for pixel up to ties, with frustum casting and ray walking.
TEST(BuildStoreMeshopt, RendersTheSameIdsAsTheDracoStore) {
  const fs::path building = scratch() / "building.ply";
  auto r = proc::run_binary(proc::gen_binary(),
                            {"building", "--triangles", "20000", "-o", building.string(), "--quiet"}, scratch());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  for (const std::string& model : {building.string(), testing::spd("tree")}) {
    SCOPED_TRACE(model);
    const std::string draco = (scratch() / "draco.frontier").string(), meshopt = (scratch() / "meshopt.frontier").string();
    build_with("draco", model, draco);
    build_with("meshopt", model, meshopt);
    if (HasFatalFailure()) return;

    Scene scenes[2];
    KdTree trees[2];
    const std::string* paths[2] = {&draco, &meshopt};
    for (int k = 0; k < 2; ++k) {
      auto model_k = StoreModel::open(*paths[k]);
      ASSERT_TRUE(model_k.is_ok()) << model_k.status().to_string();
      EXPECT_EQ((*model_k)->info().codec, k == 0 ? CellCodec::Draco : CellCodec::Meshopt);
      ASSERT_TRUE((*model_k)->load_all(scenes[k], trees[k]).is_ok());
    }
    EXPECT_EQ(triangle_multiset(scenes[1]), triangle_multiset(scenes[0]));
    EXPECT_EQ(scenes[1].size(), scenes[0].size());
    EXPECT_EQ(scenes[1].spheres.size(), scenes[0].spheres.size());
    EXPECT_EQ(scenes[1].cones.size(), scenes[0].cones.size());

    const Camera camera = scenes[0].camera ? *scenes[0].camera : automatic_camera(scenes[0].bounds());
    const View view(camera, 97, 97);
    std::vector<uint32_t> reference;
    std::vector<uint8_t> tie;
    testing::brute_reference(scenes[0], view, reference, tie);
    size_t hits = 0;
    for (uint32_t id : reference) hits += id != kNoPrim;
    EXPECT_GT(hits, view.pixels() / 10);  // the view sees the model
    for (Method m : {Method::Frustum, Method::RayWalk}) {
      const auto cmp = testing::compare_ids(reference, tie, testing::render_ids(scenes[1], trees[1], view, m), view.width);
      EXPECT_EQ(cmp.mismatches, 0u) << cmp.first_mismatch;
    }
  }
}

// A damaged meshopt page that passes its checksum (damage made before the checksum, as a
// faulty writer would) is Corruption naming the store, cell and page; never a crash.
TEST(BuildStoreMeshopt, DamagedPagesAreCorruptionNamingTheCellAndPage) {
  const std::string out = (scratch() / "damaged.frontier").string();
  build_with("meshopt", testing::spd("tree"), out);
  if (HasFatalFailure()) return;
  auto model = StoreModel::open(out);
  ASSERT_TRUE(model.is_ok()) << model.status().to_string();
  std::mt19937_64 rng(25);
  size_t pages = 0, failed = 0;
  for (uint32_t cell = 0; cell < (*model)->cells().size() && pages < 40; ++cell) {
    const StoreCell& c = (*model)->cells()[cell];
    if (c.page == StoreCell::kNoPage) continue;
    auto page = (*model)->reader().read_page(c.page);
    ASSERT_TRUE(page.is_ok());
    ASSERT_EQ(page->codec & ~kCellTreeFlag, static_cast<uint8_t>(CellCodec::Meshopt));  // with its in-cell tree
    ++pages;
    for (int trial = 0; trial < 20; ++trial) {
      std::vector<uint8_t> bytes(page->payload.begin(), page->payload.end());
      if (trial == 0) {
        bytes.resize(bytes.size() / 2);
      } else {
        bytes[rng() % bytes.size()] ^= static_cast<uint8_t>(1 + rng() % 255);
      }
      Scene decoded;
      const Status s = (*model)->decode_page(cell, page->codec, bytes, decoded);
      if (s.is_ok()) continue;
      ++failed;
      EXPECT_EQ(s.code(), Code::Corruption);
      const std::string where = fmt::format("cell {} page {}", cell, c.page);
      EXPECT_NE(s.message().find(where), std::string::npos) << s.message();
    }
  }
  EXPECT_GT(pages, 5u);
  EXPECT_GE(failed, pages);  // every truncation at least
}

}  // namespace
}  // namespace frontier
