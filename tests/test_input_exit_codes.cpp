// What frontier-build, frontier-store and frontier-view answer to bad input and bad options, run
// as users run them: exit 1 for bad input with a message naming the file, exit 2 for bad
// options (the README's rule), whatever layer finds the problem (CLI11 has exit codes of its
// own, 100 and up, that must not leak). And one rule for models with nothing in them: bad input
// in every format, for the builder and the in-memory viewer alike. Numeric options refuse NaN
// and infinities and say what is allowed in words, --threads is bounded, options a store ignores
// are refused, and a damaged store is bad input naming what is wrong (issue 43).
#include "store/byte_stream.h"
#include "store/page_format.h"
#include "tests/input_files.h"
#include "tests/process_util.h"
#include "tests/test_files.h"

#include <fmt/ranges.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

namespace frontier {
namespace {

namespace fs = std::filesystem;
using proc::run_binary;

const fs::path& scratch() { return testing::scratch_dir("frontier_input_exit"); }

proc::RunResult build(const std::vector<std::string>& args) { return run_binary(FRONTIER_BUILD_PATH, args, scratch()); }

TEST(InputExitCodes, MissingInputOrDirectoryIsBadInputNamingIt) {
  const fs::path out = scratch() / "missing.frontier";
  const fs::path dir = scratch() / "models";
  fs::create_directories(dir);
  const fs::path dir_ply = scratch() / "folder.ply";
  fs::create_directories(dir_ply);
  for (const fs::path& in : {scratch() / "missing.ply", scratch() / "missing.xyz", dir, dir_ply}) {
    const auto r = build({in.string(), "-o", out.string(), "--quiet"});
    EXPECT_EQ(r.exit_code, 1) << in << ": " << r.err;
    EXPECT_NE(r.err.find(in.string() + ": "), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(out));
  }
  // The second of two inputs, too.
  const std::string good = testing::write_file(scratch() / "good.off", testing::off_text(testing::grid_mesh(3)));
  const auto r = build({good, (scratch() / "absent.nff").string(), "-o", out.string(), "--quiet"});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find("absent.nff"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(out));
}

TEST(InputExitCodes, OptionErrorsExitTwoAndHelpZero) {
  const std::string in = testing::write_file(scratch() / "opts.off", testing::off_text(testing::grid_mesh(3)));
  const std::string out = (scratch() / "opts.frontier").string();
  const std::vector<std::vector<std::string>> bad = {
      {in, "-o", out, "--bogus"},             // unknown option
      {in},                                   // no -o
      {"-o", out},                            // no input
      {in, "-o", out, "--codec", "zip"},      // not one of the choices
      {in, "-o", out, "--tessellate", "2"},   // out of range
      {in, "-o", out, "--cell-prims", "x"},   // not a number
      {in, "-o", out, "--memory", "lots"},    // not a size
      {in, "-o", out, "--quant-bits", "40"},  // checked by the builder
  };
  for (const auto& args : bad) {
    const auto r = build(args);
    EXPECT_EQ(r.exit_code, 2) << fmt::format("{}", fmt::join(args, " ")) << ": " << r.err;
    EXPECT_FALSE(r.err.empty());
    EXPECT_FALSE(fs::exists(out));
  }
  const auto help = build({"--help"});
  EXPECT_EQ(help.exit_code, 0) << help.err;
  EXPECT_NE(help.out.find("Exit status"), std::string::npos) << help.out;
}

TEST(InputExitCodes, StoreToolMissingStoreIsOneAndBadOptionsTwo) {
  const fs::path missing = scratch() / "no_such.frontier";
  for (const char* command : {"info", "verify"}) {
    const auto r = run_binary(FRONTIER_STORE_PATH, {command, missing.string()}, scratch());
    EXPECT_EQ(r.exit_code, 1) << command << ": " << r.err;
    EXPECT_NE(r.err.find(missing.string()), std::string::npos) << r.err;
  }
  const std::vector<std::vector<std::string>> bad = {{}, {"info"}, {"frobnicate", missing.string()},
                                                     {"verify", "--bogus", missing.string()}};
  for (const auto& args : bad) {
    const auto r = run_binary(FRONTIER_STORE_PATH, args, scratch());
    EXPECT_EQ(r.exit_code, 2) << fmt::format("{}", fmt::join(args, " ")) << ": " << r.err;
  }
}

// frontier-view's option errors are 2 as well (CLI11's own codes before: 106 for an unknown
// option or a missing model), --help 0.
TEST(InputExitCodes, ViewerOptionErrorsExitTwo) {
  const std::vector<std::vector<std::string>> bad = {{}, {"--bogus"}, {"model.nff", "--size", "abc"},
                                                     {"model.nff", "--threads", "x"}};
  for (const auto& args : bad) {
    const auto r = run_binary(FRONTIER_VIEW_PATH, args, scratch());
    EXPECT_EQ(r.exit_code, 2) << fmt::format("{}", fmt::join(args, " ")) << ": " << r.err;
  }
  EXPECT_EQ(run_binary(FRONTIER_VIEW_PATH, {"--help"}, scratch()).exit_code, 0);
}

std::string args_text(const std::vector<std::string>& args) { return fmt::format("{}", fmt::join(args, " ")); }

// --threads 100000 took 3.7 GB for a 64x64 frame and, in one run of two, a segmentation fault (a
// worker's 16-bit index wrapped around); every program that has --threads bounds it.
TEST(InputExitCodes, ThreadsAreBoundedInEveryProgram) {
  const std::string in = testing::write_file(scratch() / "threads.off", testing::off_text(testing::grid_mesh(3)));
  const std::string out = (scratch() / "threads.frontier").string();
  const std::string most = std::to_string(4 * std::max(1u, std::thread::hardware_concurrency()));
  for (const std::string& threads : {std::string("100000"), std::to_string(std::stoi(most) + 1), std::string("-1")}) {
    const auto b = build({in, "-o", out, "--quiet", "--threads", threads});
    EXPECT_EQ(b.exit_code, 2) << threads << ": " << b.err;
    EXPECT_NE(b.err.find("--threads: must be 0 (all cores) to " + most), std::string::npos) << b.err;
    EXPECT_FALSE(fs::exists(out));
    const auto v = run_binary(FRONTIER_VIEW_PATH, {in, "--headless", "--size", "16x16", "--threads", threads}, scratch());
    EXPECT_EQ(v.exit_code, 2) << threads << ": " << v.err;
    EXPECT_NE(v.err.find("--threads: must be 0 (all cores) to " + most), std::string::npos) << v.err;
  }
  const auto b = build({in, "-o", out, "--quiet", "--threads", most});
  EXPECT_EQ(b.exit_code, 0) << b.err;
  const auto v = run_binary(FRONTIER_VIEW_PATH, {out, "--headless", "--size", "16x16", "--threads", most}, scratch());
  EXPECT_EQ(v.exit_code, 0) << v.err;
}

// NaN and the infinities slipped past every range check (each comparison with NaN is false):
// --frame-ms nan ran with exit 0. Every floating option of every program refuses them.
TEST(InputExitCodes, NanAndInfinityAreRefusedInEveryFloatingOption) {
  const std::string in = testing::write_file(scratch() / "finite.off", testing::off_text(testing::grid_mesh(3)));
  const std::string out = (scratch() / "finite.frontier").string();
  const std::vector<std::pair<std::string, std::vector<std::string>>> programs = {
      {FRONTIER_VIEW_PATH, {"--frame-ms", "--min-sampled", "--pixel-error", "--eye-height", "--radius"}},
      {FRONTIER_BUILD_PATH, {"--sdf-voxel", "--walk-radius"}},
  };
  for (const auto& [program, options] : programs) {
    for (const std::string& option : options) {
      for (const char* value : {"nan", "NaN", "-nan", "inf", "-inf", "infinity", "1e999"}) {
        const std::vector<std::string> args = {in, "-o", out, "--headless", option, value};
        // frontier-view has no -o and frontier-build no --headless: drop what the program lacks.
        std::vector<std::string> used;
        for (size_t i = 0; i < args.size(); ++i) {
          if (program == FRONTIER_VIEW_PATH && args[i] == "-o") {
            ++i;
            continue;
          }
          if (program == FRONTIER_BUILD_PATH && args[i] == "--headless") continue;
          used.push_back(args[i]);
        }
        const auto r = run_binary(program, used, scratch());
        EXPECT_EQ(r.exit_code, 2) << args_text(used) << ": " << r.err;
        EXPECT_NE(r.err.find(option + ": must be a finite number"), std::string::npos) << args_text(used) << ": " << r.err;
        EXPECT_FALSE(fs::exists(out));
      }
    }
  }
  // frontier-gen's too.
  const std::string ply = (scratch() / "finite.ply").string();
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"terrain", "--triangles", "100", "-o", ply, "--relief", "nan"},
        {"terrain", "--triangles", "100", "-o", ply, "--spacing", "inf"},
        {"building", "--triangles", "1000", "-o", ply, "--furniture", "nan"}}) {
    const auto r = run_binary(proc::gen_binary(), args, scratch());
    EXPECT_EQ(r.exit_code, 2) << args_text(args) << ": " << r.err;
    EXPECT_NE(r.err.find(args[5] + ": must be a finite number"), std::string::npos) << args_text(args) << ": " << r.err;
    EXPECT_FALSE(fs::exists(ply));
  }
}

// Out of range said "Value 0 not in range 0.000000 to 1797693134862315708…" (300 digits).
TEST(InputExitCodes, OutOfRangeSaysWhatIsAllowedInWords) {
  const std::string in = testing::write_file(scratch() / "range.off", testing::off_text(testing::grid_mesh(3)));
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"--frame-ms", "0"}, "--frame-ms: must be > 0, not 0"},
      {{"--samples", "0"}, "--samples: must be > 0, not 0"},
      {{"--pixel-error", "-1"}, "--pixel-error: must be >= 0, not -1"},
      {{"--min-sampled", "2"}, "--min-sampled: must be between 0 and 1, not 2"},
      {{"--png-every", "0"}, "--png-every: must be > 0, not 0"},
      {{"--frames", "-3"}, "--frames: must be >= 0, not -3"},
  };
  for (const auto& [options, message] : cases) {
    std::vector<std::string> args = {in, "--headless", "--size", "16x16"};
    args.insert(args.end(), options.begin(), options.end());
    const auto r = run_binary(FRONTIER_VIEW_PATH, args, scratch());
    EXPECT_EQ(r.exit_code, 2) << args_text(args) << ": " << r.err;
    EXPECT_NE(r.err.find(message), std::string::npos) << r.err;
    EXPECT_EQ(r.err.find("not in range"), std::string::npos) << r.err;
  }
}

std::string small_store(const std::string& name) {
  const std::string out = (scratch() / (name + ".frontier")).string();
  if (!fs::exists(out)) {
    const auto r = build({testing::spd("rings"), "-o", out, "--codec", "raw", "--quiet"});
    EXPECT_EQ(r.exit_code, 0) << r.err;
  }
  return out;
}

// --method imr on a store was ignored without a word (a store is walked by frustum casting): it
// and the options only the in-memory methods read are bad options there; with --in-memory they
// apply.
TEST(InputExitCodes, InMemoryMethodsOnAPagedStoreAreRefused) {
  const std::string store = small_store("methods");
  const std::vector<std::pair<std::vector<std::string>, std::string>> refused = {
      {{"--method", "imr"}, "--method imr renders a model file, or a store with --in-memory"},
      {{"--method", "brute"}, "--method brute renders a model file, or a store with --in-memory"},
      {{"--method", "bsp"}, "--method bsp renders a model file"},
      {{"--order", "random"}, "--order is read by --method imr, tessellated, mesa or bsp"},
      {{"--bound-slices", "8"}, "--bound-slices is read by"},
      {{"--aa", "4x4"}, "--aa is read by"},
  };
  for (const auto& [options, message] : refused) {
    std::vector<std::string> args = {store, "--headless", "--size", "16x16"};
    args.insert(args.end(), options.begin(), options.end());
    auto r = run_binary(FRONTIER_VIEW_PATH, args, scratch());
    EXPECT_EQ(r.exit_code, 2) << args_text(args) << ": " << r.err;
    EXPECT_NE(r.err.find(message), std::string::npos) << r.err;
    args.push_back("--in-memory");
    r = run_binary(FRONTIER_VIEW_PATH, args, scratch());
    EXPECT_EQ(r.exit_code, 0) << args_text(args) << ": " << r.err;
  }
  // What a store is walked with may be named.
  const auto r = run_binary(FRONTIER_VIEW_PATH, {store, "--headless", "--size", "16x16", "--method", "frustum"}, scratch());
  EXPECT_EQ(r.exit_code, 0) << r.err;
}

// A damaged store (the first byte flipped or zeroed, cut to nothing, not a store, from a newer
// frontier) or a missing one said "unknown model format '.frontier'" for a frame and "--path ...
// need a store" (exit 2) for a walk. Any *.frontier path is opened as a store and what is wrong
// with it is bad input (exit 1), for a frame, a walk and --in-memory alike.
TEST(InputExitCodes, DamagedOrMissingStoreIsBadInputSayingWhatIsWrong) {
  const std::string good = small_store("damaged_source");
  const std::string bytes = proc::slurp(good);
  ASSERT_GT(bytes.size(), store::kHeaderSize + store::kFooterSize);
  const auto damaged = [&](const std::string& name, const std::string& contents) {
    const std::string path = (scratch() / name).string();
    std::ofstream(path, std::ios::binary) << contents;
    return path;
  };
  std::string flipped = bytes, zeroed = bytes, newer = bytes;
  flipped[0] = static_cast<char>(flipped[0] ^ 0x01);
  zeroed[0] = '\0';
  {
    // Header and footer say version 7, their checksums right: a store from a newer frontier.
    const auto header = store::encode_header(store::Header{7, 0});
    std::copy(header.begin(), header.end(), newer.begin());
    const size_t f = newer.size() - store::kFooterSize;
    const auto* footer_bytes = reinterpret_cast<const uint8_t*>(newer.data() + f);
    const store::Footer footer{{store::get_u64(footer_bytes), store::get_u64(footer_bytes + 8)}, 7};
    const auto encoded = store::encode_footer(footer);
    std::copy(encoded.begin(), encoded.end(), newer.begin() + static_cast<std::ptrdiff_t>(f));
  }
  const std::string cam = testing::write_file(scratch() / "damaged.cam", "");
  const std::vector<std::pair<std::string, std::string>> cases = {
      {damaged("flipped.frontier", flipped), "damaged header (bytes 0-7 are not the magic FRNTSTOR)"},
      {damaged("zeroed.frontier", zeroed), "damaged header (bytes 0-7 are not the magic FRNTSTOR)"},
      {damaged("empty.frontier", ""), "truncated store (0 bytes"},
      {damaged("text.frontier", std::string(200, 'a')), "not a frontier store"},
      {damaged("newer.frontier", newer), "format version 7 is newer than this reader"},
      {(scratch() / "no_such_store.frontier").string(), "no such file"},
  };
  for (const auto& [path, message] : cases) {
    for (const std::vector<std::string>& mode : {std::vector<std::string>{"--headless", "--size", "16x16"},
                                                 {"--headless", "--path", cam, "--report", "r.jsonl"},
                                                 {"--headless", "--size", "16x16", "--in-memory"}}) {
      std::vector<std::string> args = {path};
      args.insert(args.end(), mode.begin(), mode.end());
      const auto r = run_binary(FRONTIER_VIEW_PATH, args, scratch());
      EXPECT_EQ(r.exit_code, 1) << args_text(args) << ": " << r.err;
      EXPECT_NE(r.err.find(path + ": " + message), std::string::npos) << args_text(args) << ": " << r.err;
    }
    // frontier-store says the same.
    const auto r = run_binary(FRONTIER_STORE_PATH, {"verify", path}, scratch());
    EXPECT_EQ(r.exit_code, 1) << r.err;
    EXPECT_NE(r.err.find(path + ": " + message), std::string::npos) << r.err;
  }
}

// Every format with no primitives: a 0-byte file where the format allows it, else the smallest
// well-formed file that declares nothing.
TEST(InputEmptyModel, NoPrimitivesIsBadInputInEveryFormat) {
  const testing::TriangleMesh none;
  const std::vector<std::pair<std::string, std::string>> files = {
      {"empty.nff", ""},
      {"comments.nff", "# nothing but a comment\nv\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 45\n"},
      {"empty.obj", ""},
      {"vertices.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n"},
      {"empty.off", "OFF\n0 0 0\n"},
      {"empty.ply", testing::ply_ascii(none)},
      {"empty_bin.ply", testing::ply_binary(none)},
      {"empty.stl", "solid nothing\nendsolid nothing\n"},
      {"empty_bin.stl", testing::stl_binary(none)},
  };
  const fs::path out = scratch() / "empty.frontier";
  for (const auto& [name, bytes] : files) {
    const std::string in = testing::write_file(scratch() / name, bytes);
    const auto r = build({in, "-o", out.string(), "--quiet"});
    EXPECT_EQ(r.exit_code, 1) << name << ": " << r.err;
    EXPECT_NE(r.err.find(in + ": the model has no primitives"), std::string::npos) << name << ": " << r.err;
    EXPECT_FALSE(fs::exists(out)) << name;
    // The in-memory viewer holds the same rule.
    const auto v = run_binary(FRONTIER_VIEW_PATH, {in, "--headless", "--size", "16x16"}, scratch());
    EXPECT_EQ(v.exit_code, 1) << name << ": " << v.err;
    EXPECT_NE(v.err.find(in + ": the model has no primitives"), std::string::npos) << name << ": " << v.err;
  }
  // An empty input beside a good one is still named.
  const std::string good = testing::write_file(scratch() / "good.off", testing::off_text(testing::grid_mesh(3)));
  const auto r = build({good, (scratch() / "empty.obj").string(), "-o", out.string(), "--quiet"});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find("empty.obj: the model has no primitives"), std::string::npos) << r.err;
}

TEST(InputEmptyModel, OnlyDegeneratePrimitivesIsBadInput) {
  const std::string in = testing::write_file(scratch() / "flat.off", "OFF\n3 2 0\n0 0 0\n1 0 0\n2 0 0\n3 0 1 2\n3 2 1 0\n");
  const fs::path out = scratch() / "flat.frontier";
  const auto r = build({in, "-o", out.string(), "--quiet"});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find(in + ": the model has no primitives left: all 2 are degenerate"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(out));
  const auto v = run_binary(FRONTIER_VIEW_PATH, {in, "--headless", "--size", "16x16"}, scratch());
  EXPECT_EQ(v.exit_code, 1) << v.err;
  EXPECT_NE(v.err.find("all 2 are degenerate"), std::string::npos) << v.err;
}

}  // namespace
}  // namespace frontier
