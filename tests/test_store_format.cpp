// Store framing, writer and reader: round trips, and every kind of damage (flipped bytes,
// truncation, foreign or newer files, failing writes) ends in a clear Status, never a crash.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <random>
#include <stdexcept>

#include "store/mem_file.h"
#include "store/page_format.h"
#include "store/store_file.h"

namespace frontier::store {
namespace {

using Code = Status::Code;

std::vector<uint8_t> pattern(size_t n, uint32_t seed) {
  std::vector<uint8_t> v(n);
  std::mt19937 rng(seed);
  for (auto& b : v) b = static_cast<uint8_t>(rng());
  return v;
}

struct Written {
  std::vector<std::vector<uint8_t>> pages;
  std::vector<uint8_t> codecs;
  std::vector<uint8_t> cells, tree;
};

// Writes a store of `n` pages with sizes up to max_size; returns what was written.
Written write_store(FileSystem& fs, const std::string& path, int n, size_t max_size,
                    uint32_t seed) {
  Written w;
  std::mt19937 rng(seed);
  auto writer = StoreWriter::create(fs, path);
  EXPECT_TRUE(writer.is_ok()) << writer.status().to_string();
  for (int i = 0; i < n; ++i) {
    w.pages.push_back(pattern(rng() % (max_size + 1), rng()));
    w.codecs.push_back(static_cast<uint8_t>(rng() % 3));
    auto id = (*writer)->add_page(w.codecs.back(), w.pages.back());
    EXPECT_TRUE(id.is_ok());
    EXPECT_EQ(id.value(), static_cast<PageId>(i));
  }
  w.cells = pattern(40, seed + 1);
  w.tree = pattern(24, seed + 2);
  EXPECT_TRUE((*writer)->add_section("cells", w.cells).is_ok());
  EXPECT_TRUE((*writer)->add_section("tree", w.tree).is_ok());
  Status s = (*writer)->finish();
  EXPECT_TRUE(s.is_ok()) << s.to_string();
  return w;
}

void expect_reads_back(FileSystem& fs, const std::string& path, const Written& w) {
  auto reader = StoreReader::open(fs, path);
  ASSERT_TRUE(reader.is_ok()) << reader.status().to_string();
  const StoreReader& r = *reader.value();
  EXPECT_EQ(r.version(), kFormatVersion);
  ASSERT_EQ(r.page_count(), w.pages.size());
  for (size_t i = 0; i < w.pages.size(); ++i) {
    auto page = r.read_page(i);
    ASSERT_TRUE(page.is_ok()) << page.status().to_string();
    EXPECT_EQ(page->codec, w.codecs[i]);
    EXPECT_EQ(page->payload, w.pages[i]);
  }
  EXPECT_EQ(r.read_section("cells").value(), w.cells);
  EXPECT_EQ(r.read_section("tree").value(), w.tree);
  EXPECT_EQ(r.read_section("sdf").status().code(), Code::NotFound);
  EXPECT_EQ(r.read_page(w.pages.size()).status().code(), Code::InvalidArgument);
  EXPECT_TRUE(r.verify().is_ok());
}

// Rewrites the version in header and footer (with valid checksums), as a newer writer would.
std::vector<uint8_t> with_version(std::vector<uint8_t> bytes, uint32_t version) {
  auto header = encode_header(Header{version, 0});
  std::copy(header.begin(), header.end(), bytes.begin());
  size_t f = bytes.size() - kFooterSize;
  Footer footer{{get_u64(&bytes[f]), get_u64(&bytes[f + 8])}, version};
  auto fb = encode_footer(footer);
  std::copy(fb.begin(), fb.end(), bytes.begin() + static_cast<std::ptrdiff_t>(f));
  return bytes;
}

TEST(StoreFormat, PageRoundTripAndEveryFlipDetected) {
  std::vector<uint8_t> payload = pattern(57, 1);
  std::vector<uint8_t> block = encode_page(7, payload);
  ASSERT_EQ(block.size(), payload.size() + kBlockTrailerSize);
  Handle h{1000, block.size()};
  auto decoded = decode_page(block, h);
  ASSERT_TRUE(decoded.is_ok());
  EXPECT_EQ(decoded->codec, 7);
  EXPECT_TRUE(std::equal(payload.begin(), payload.end(), decoded->payload.begin(),
                         decoded->payload.end()));
  for (size_t i = 0; i < block.size(); ++i) {
    for (uint8_t mask : {0x01, 0x80, 0xFF}) {
      std::vector<uint8_t> bad = block;
      bad[i] ^= mask;
      auto r = decode_page(bad, h);
      ASSERT_FALSE(r.is_ok()) << "byte " << i;
      EXPECT_EQ(r.status().code(), Code::Corruption);
      EXPECT_NE(r.status().message().find("page at offset 1000"), std::string::npos);
    }
  }
  for (size_t n = 0; n < block.size(); ++n) {
    std::span<const uint8_t> cut(block.data(), n);
    EXPECT_EQ(decode_page(cut, h).status().code(), Code::Corruption);
    EXPECT_EQ(decode_page(cut, Handle{0, n}).status().code(), Code::Corruption);
  }
  // An empty payload is a valid page.
  auto empty = encode_page(kCodecRaw, {});
  EXPECT_TRUE(decode_page(empty, Handle{0, empty.size()}).is_ok());
}

TEST(StoreFormat, HeaderFooterVersionAndMagic) {
  auto header = encode_header(Header{});
  EXPECT_TRUE(decode_header(header, "x").is_ok());
  auto footer = encode_footer(Footer{{24, 100}, kFormatVersion});
  auto f = decode_footer(footer, "x");
  ASSERT_TRUE(f.is_ok());
  EXPECT_EQ(f->directory, (Handle{24, 100}));

  auto newer = decode_footer(encode_footer(Footer{{24, 100}, 7}), "store.frontier");
  EXPECT_EQ(newer.status().code(), Code::Unsupported);
  EXPECT_EQ(newer.status().message(),
            "store.frontier: format version 7 is newer than this reader (1)");
  EXPECT_EQ(decode_header(encode_header(Header{7, 0}), "s").status().code(), Code::Unsupported);
  EXPECT_EQ(decode_header(encode_header(Header{1, 4}), "s").status().code(), Code::Unsupported);

  auto bad_magic = footer;
  bad_magic[35] = 'X';
  EXPECT_NE(decode_footer(bad_magic, "x").status().message().find("magic"), std::string::npos);
  auto bad_header = header;
  bad_header[0] = 'X';
  EXPECT_NE(decode_header(bad_header, "x").status().message().find("magic"), std::string::npos);
}

TEST(StoreFormat, DirectoryAndIndexRejectGarbage) {
  std::vector<Section> sections = {{"cells", {24, 30}}, {"pages", {54, 25}}};
  auto dir = encode_directory(sections);
  auto back = decode_directory(dir, {}, "x");
  ASSERT_TRUE(back.is_ok());
  ASSERT_EQ(back->size(), 2u);
  EXPECT_EQ((*back)[1].name, "pages");
  for (size_t n = 0; n < dir.size(); ++n) {
    EXPECT_FALSE(decode_directory(std::span(dir.data(), n), {}, "x").is_ok()) << n;
  }
  auto dup = encode_directory({{"a", {}}, {"a", {}}});
  EXPECT_EQ(decode_directory(dup, {}, "x").status().code(), Code::Corruption);

  auto index = encode_page_index({{24, 10}, {34, 12}});
  EXPECT_EQ(decode_page_index(index, {}, "x").value().size(), 2u);
  for (size_t n = 0; n < index.size(); ++n) {
    EXPECT_FALSE(decode_page_index(std::span(index.data(), n), {}, "x").is_ok()) << n;
  }
  auto huge = index;
  huge[7] = 0xFF;  // count far larger than the payload
  EXPECT_EQ(decode_page_index(huge, {}, "x").status().code(), Code::Corruption);
}

TEST(StoreFile, RoundTripInMemory) {
  MemFileSystem fs;
  Written w = write_store(fs, "s.frontier", 50, 3000, 42);
  EXPECT_FALSE(fs.exists("s.frontier.tmp"));
  expect_reads_back(fs, "s.frontier", w);
}

TEST(StoreFile, EmptyStoreRoundTrip) {
  MemFileSystem fs;
  auto writer = StoreWriter::create(fs, "e");
  ASSERT_TRUE(writer.is_ok());
  ASSERT_TRUE((*writer)->finish().is_ok());
  auto r = StoreReader::open(fs, "e");
  ASSERT_TRUE(r.is_ok()) << r.status().to_string();
  EXPECT_EQ((*r)->page_count(), 0u);
  EXPECT_TRUE((*r)->verify().is_ok());
}

TEST(StoreFile, RoundTripRealFile) {
  std::filesystem::path dir = std::filesystem::temp_directory_path() /
                              ("frontier_store_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  std::string path = (dir / "store.frontier").string();
  for (bool cold : {false, true}) {
    PosixFileSystem fs(cold);
    Written w = write_store(fs, path, 30, 5000, cold ? 7 : 8);
    EXPECT_TRUE(std::filesystem::exists(path));
    EXPECT_FALSE(std::filesystem::exists(path + ".tmp"));
    expect_reads_back(fs, path, w);
  }
  PosixFileSystem fs;
  EXPECT_EQ(StoreReader::open(fs, (dir / "missing").string()).status().code(), Code::NotFound);
  // A writer abandoned half way leaves the old store in place and no .tmp behind.
  {
    auto writer = StoreWriter::create(fs, path);
    ASSERT_TRUE(writer.is_ok());
    ASSERT_TRUE((*writer)->add_page(0, pattern(100, 1)).is_ok());
    EXPECT_TRUE(std::filesystem::exists(path + ".tmp"));
  }
  EXPECT_FALSE(std::filesystem::exists(path + ".tmp"));
  EXPECT_TRUE(StoreReader::open(fs, path).is_ok());
  // Creating in a directory that does not exist is an IoError, not a crash.
  auto bad = StoreWriter::create(fs, (dir / "no" / "such" / "dir.frontier").string());
  EXPECT_EQ(bad.status().code(), Code::IoError);
  std::filesystem::remove_all(dir);
}

// Every single-byte change anywhere (header, pages, sections, page index, directory, footer)
// is reported as Corruption by open() or verify().
TEST(StoreFile, EveryFlippedByteIsCorruption) {
  MemFileSystem fs;
  write_store(fs, "s", 12, 120, 3);
  const std::vector<uint8_t> good = fs.contents("s");
  ASSERT_GE(good.size(), 600u);
  auto r = StoreReader::open(fs, "s");
  ASSERT_TRUE(r.is_ok());
  Handle page5 = (*r)->page_handle(5);

  std::mt19937 rng(11);
  int checked = 0;
  // Every position with a full-byte flip, plus random single-bit flips, >= 1000 in all.
  std::vector<std::pair<size_t, uint8_t>> flips;
  for (size_t i = 0; i < good.size(); ++i) flips.push_back({i, 0xFF});
  while (flips.size() < good.size() + 1000) {
    flips.push_back({rng() % good.size(), static_cast<uint8_t>(1u << (rng() % 8))});
  }
  for (auto [pos, mask] : flips) {
    std::vector<uint8_t> bad = good;
    bad[pos] ^= mask;
    fs.set_contents("bad", bad);
    auto reader = StoreReader::open(fs, "bad");
    Status s = reader.is_ok() ? (*reader)->verify() : reader.status();
    ASSERT_FALSE(s.is_ok()) << "flip at " << pos << " went unnoticed";
    EXPECT_EQ(s.code(), Code::Corruption) << s.to_string();
    if (pos >= page5.offset && pos < page5.offset + page5.size) {
      EXPECT_NE(s.message().find("page at offset " + std::to_string(page5.offset)),
                std::string::npos)
          << s.message();
      ASSERT_TRUE(reader.is_ok());
      EXPECT_EQ((*reader)->read_page(5).status().code(), Code::Corruption);
      EXPECT_TRUE((*reader)->read_page(4).is_ok());
    }
    ++checked;
  }
  EXPECT_GE(checked, 1000);
}

TEST(StoreFile, TruncatedAtEveryLengthIsAnError) {
  MemFileSystem fs;
  write_store(fs, "s", 10, 100, 5);
  const std::vector<uint8_t> good = fs.contents("s");
  for (size_t n = 0; n < good.size(); ++n) {
    fs.set_contents("t", std::vector<uint8_t>(good.begin(), good.begin() + n));
    auto r = StoreReader::open(fs, "t");
    ASSERT_FALSE(r.is_ok()) << "length " << n;
    EXPECT_EQ(r.status().code(), Code::Corruption) << r.status().to_string();
    EXPECT_FALSE(r.status().message().empty());
  }
  // A reader opened before the file was truncated reports the missing bytes on read.
  auto r = StoreReader::open(fs, "s");
  ASSERT_TRUE(r.is_ok());
  fs.truncate("s", kHeaderSize + 5);
  EXPECT_EQ((*r)->read_page(0).status().code(), Code::Corruption);
  EXPECT_FALSE((*r)->verify().is_ok());
}

TEST(StoreFile, ForeignAndNewerFilesAreRejectedClearly) {
  MemFileSystem fs;
  write_store(fs, "s", 4, 100, 9);
  const std::vector<uint8_t> good = fs.contents("s");

  fs.set_contents("v7", with_version(good, 7));
  auto v7 = StoreReader::open(fs, "v7");
  EXPECT_EQ(v7.status().code(), Code::Unsupported);
  EXPECT_EQ(v7.status().message(), "v7: format version 7 is newer than this reader (1)");
  // Same version rewritten is still a valid store (the helper itself is right).
  fs.set_contents("v1", with_version(good, 1));
  EXPECT_TRUE(StoreReader::open(fs, "v1").is_ok());

  fs.set_contents("text", std::vector<uint8_t>(200, 'a'));
  auto text = StoreReader::open(fs, "text");
  EXPECT_EQ(text.status().code(), Code::Corruption);
  EXPECT_NE(text.status().message().find("not a frontier store"), std::string::npos);

  EXPECT_EQ(StoreReader::open(fs, "missing").status().code(), Code::NotFound);
}

// Footers with valid checksums but forged directory handles (a hostile or buggy writer) are
// rejected before anything is allocated or read from them.
TEST(StoreFile, ForgedFooterHandlesAreRejected) {
  MemFileSystem fs;
  write_store(fs, "s", 4, 100, 9);
  const std::vector<uint8_t> good = fs.contents("s");
  const uint64_t size = good.size();
  const uint64_t end = size - kFooterSize;
  const uint64_t huge = ~uint64_t{0};
  std::vector<Handle> forged = {{0, end},          {end, 0},           {end - 5, 5},
                                {end + 8, huge - 7}, {huge, end + 1},  {24, huge},
                                {size, huge - size + end + 1}, {huge - 3, end + 4}};
  for (Handle h : forged) {
    std::vector<uint8_t> bad = good;
    auto footer = encode_footer(Footer{h, kFormatVersion});
    std::copy(footer.begin(), footer.end(), bad.begin() + static_cast<std::ptrdiff_t>(end));
    fs.set_contents("bad", bad);
    auto r = StoreReader::open(fs, "bad");
    ASSERT_FALSE(r.is_ok()) << h.offset << " " << h.size;
    EXPECT_EQ(r.status().code(), Code::Corruption);
  }
}

TEST(StoreWriter, FailedWriteLeavesNoFileAndKeepsTheOldStore) {
  // Count the appends of a full write, then fail each one in turn.
  MemFileSystem probe;
  write_store(probe, "s", 6, 50, 1);
  const int appends = probe.append_count();
  ASSERT_GT(appends, 8);
  for (int n = 1; n <= appends; ++n) {
    MemFileSystem fs;
    Written old = write_store(fs, "s", 3, 50, 2);  // an older store already at the name
    fs.fail_nth_append(n);
    {
      auto writer = StoreWriter::create(fs, "s");
      Status first;
      if (!writer.is_ok()) {
        first = writer.status();
      } else {
        std::mt19937 rng(1);
        for (int i = 0; i < 6 && first.is_ok(); ++i) {
          auto id = (*writer)->add_page(0, pattern(rng() % 51, rng()));
          if (!id.is_ok()) first = id.status();
        }
        if (first.is_ok()) first = (*writer)->add_section("cells", pattern(40, 3));
        if (first.is_ok()) first = (*writer)->add_section("tree", pattern(24, 4));
        if (first.is_ok()) first = (*writer)->finish();
        // After a failure every call returns the same error.
        if (!first.is_ok()) {
          EXPECT_EQ((*writer)->finish().message(), first.message());
        }
      }
      EXPECT_EQ(first.code(), Code::IoError) << "append " << n;
      EXPECT_FALSE(fs.exists("s.tmp")) << "append " << n;
    }
    EXPECT_EQ(fs.list(), std::vector<std::string>{"s"});
    expect_reads_back(fs, "s", old);
  }
}

TEST(StoreWriter, SyncOrRenameFailureLeavesNoFile) {
  for (int which = 0; which < 2; ++which) {
    MemFileSystem fs;
    (which == 0 ? [](MemFileSystem& f) { f.fail_sync(true); }
                : [](MemFileSystem& f) { f.fail_rename(true); })(fs);
    auto writer = StoreWriter::create(fs, "s");
    ASSERT_TRUE(writer.is_ok());
    ASSERT_TRUE((*writer)->add_page(0, pattern(10, 1)).is_ok());
    EXPECT_EQ((*writer)->finish().code(), Code::IoError);
    EXPECT_TRUE(fs.list().empty());
  }
}

TEST(StoreWriter, ExceptionOrAbandonLeavesNoFile) {
  MemFileSystem fs;
  try {
    auto writer = StoreWriter::create(fs, "s");
    ASSERT_TRUE(writer.is_ok());
    ASSERT_TRUE((*writer)->add_page(0, pattern(10, 1)).is_ok());
    EXPECT_TRUE(fs.exists("s.tmp"));
    throw std::runtime_error("preprocessor failed");
  } catch (const std::runtime_error&) {
  }
  EXPECT_TRUE(fs.list().empty());
}

TEST(StoreWriter, RejectsBadSectionNames) {
  MemFileSystem fs;
  auto writer = StoreWriter::create(fs, "s");
  ASSERT_TRUE(writer.is_ok());
  std::vector<uint8_t> none;
  EXPECT_EQ((*writer)->add_section("", none).code(), Code::InvalidArgument);
  EXPECT_EQ((*writer)->add_section("pages", none).code(), Code::InvalidArgument);
  EXPECT_EQ((*writer)->add_section(std::string(256, 'x'), none).code(), Code::InvalidArgument);
  EXPECT_TRUE((*writer)->add_section("sdf", none).is_ok());
  EXPECT_EQ((*writer)->add_section("sdf", none).code(), Code::InvalidArgument);
  ASSERT_TRUE((*writer)->finish().is_ok());
  auto r = StoreReader::open(fs, "s");
  ASSERT_TRUE(r.is_ok());
  EXPECT_TRUE((*r)->read_section("sdf").value().empty());
}

}  // namespace
}  // namespace frontier::store
