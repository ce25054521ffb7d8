// .cam camera paths: exact write/read round trip and errors that name the line.
#include "src/io/camera_path.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <string>
#include <vector>

namespace frontier {
namespace {

Camera frame(Vec3 eye, Vec3 at, Vec3 up, double vfov) {
  Camera c;
  c.eye = eye;
  c.look_at = at;
  c.up = up;
  c.vfov_deg = vfov;
  return c;
}

std::vector<Camera> sample_frames() {
  return {frame({0, 0, 1.7}, {1, 0, 1.7}, {0, 0, 1}, 60),
          frame({0.1, 0.2, 0.3}, {-123.456789012345, 1e-7, 3.3}, {0, 0.1, 1}, 45.5),
          frame({1e12, -1e-300, 7}, {1e12 + 1, 2, 7}, {0, 0, -1}, 1e-3),
          frame({1.0 / 3.0, 2.0 / 3.0, std::nextafter(1.0, 2.0)}, {5, 5, 5}, {1, 0, 0}, 179.9)};
}

TEST(CameraPath, WriteThenReadIsExact) {
  const std::vector<Camera> frames = sample_frames();
  const std::string text = format_camera_path(frames, {"a comment", "two\nlines"});
  auto back = parse_camera_path(text, "mem.cam");
  ASSERT_TRUE(back.is_ok()) << back.status().to_string();
  ASSERT_EQ(back->size(), frames.size());
  for (size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ((*back)[i].eye, frames[i].eye) << i;
    EXPECT_EQ((*back)[i].look_at, frames[i].look_at) << i;
    EXPECT_EQ((*back)[i].up, frames[i].up) << i;
    EXPECT_EQ((*back)[i].vfov_deg, frames[i].vfov_deg) << i;
  }
}

TEST(CameraPath, FileRoundTrip) {
  const std::string path = testing::TempDir() + "camera_path_round_trip.cam";
  ASSERT_TRUE(write_camera_path(path, sample_frames(), {"test"}).is_ok());
  auto back = read_camera_path(path);
  ASSERT_TRUE(back.is_ok()) << back.status().to_string();
  EXPECT_EQ(back->size(), sample_frames().size());
  EXPECT_EQ(back->back().vfov_deg, 179.9);
  std::remove(path.c_str());
}

TEST(CameraPath, CommentsBlankLinesTabsAndCrlfAreAccepted) {
  const std::string text =
      "# header\r\n\r\n   \n"
      "0 0 1.7\t1 0 1.7\t0 0 1\t60\r\n"
      "  # indented comment\n"
      "+1 2 3  4 5 6  0 0 1  30";  // no final newline, explicit '+'
  auto back = parse_camera_path(text, "x.cam");
  ASSERT_TRUE(back.is_ok()) << back.status().to_string();
  ASSERT_EQ(back->size(), 2u);
  EXPECT_EQ((*back)[1].eye, Vec3(1, 2, 3));
  EXPECT_EQ((*back)[1].vfov_deg, 30.0);
}

TEST(CameraPath, EmptyFileHasNoFrames) {
  auto back = parse_camera_path("# nothing\n\n", "e.cam");
  ASSERT_TRUE(back.is_ok());
  EXPECT_TRUE(back->empty());
}

void expect_error_at_line(const std::string& text, int line, const std::string& fragment) {
  auto r = parse_camera_path(text, "bad.cam");
  ASSERT_FALSE(r.is_ok()) << "accepted: " << text;
  const std::string msg = r.status().message();
  EXPECT_NE(msg.find("bad.cam: line " + std::to_string(line) + ":"), std::string::npos) << msg;
  EXPECT_NE(msg.find(fragment), std::string::npos) << msg;
}

TEST(CameraPath, MalformedLinesNameTheLine) {
  const std::string good = "0 0 0  1 0 0  0 0 1  60\n";
  expect_error_at_line(good + "# c\n0 0 0  1 0 0  0 0 1\n", 3, "got 9");
  expect_error_at_line(good + "0 0 0  1 0 0  0 0 1  60 7\n", 2, "more than 10");
  expect_error_at_line("0 0 zero  1 0 0  0 0 1  60\n", 1, "'zero' is not a number");
  expect_error_at_line(good + good + "0 0 0  1 0 0  0 0 1  60x\n", 3, "not a number");
  expect_error_at_line("0 0 0  1 0 0  0 0 1  nan\n", 1, "non-finite");
  expect_error_at_line("0 0 0  1 0 0  0 0 1  inf\n", 1, "non-finite");
  expect_error_at_line("0 0 0  1 0 0  0 0 1  0\n", 1, "field of view");
  expect_error_at_line("0 0 0  1 0 0  0 0 1  180\n", 1, "field of view");
  expect_error_at_line("1 2 3  1 2 3  0 0 1  60\n", 1, "equals the eye");
  expect_error_at_line("0 0 0  1 0 0  0 0 0  60\n", 1, "zero");
  expect_error_at_line("0 0 0  0 0 5  0 0 1  60\n", 1, "parallel");
}

TEST(CameraPath, WriterRejectsInvalidFramesAndNamesThem) {
  std::vector<Camera> frames = sample_frames();
  frames[2].vfov_deg = -1;
  const Status st = write_camera_path(testing::TempDir() + "never.cam", frames);
  ASSERT_FALSE(st.is_ok());
  EXPECT_NE(st.message().find("frame 2"), std::string::npos) << st.message();
}

TEST(CameraPath, MissingFileIsNotFound) {
  auto r = read_camera_path("/nonexistent/dir/path.cam");
  ASSERT_FALSE(r.is_ok());
  EXPECT_EQ(r.status().code(), Status::Code::NotFound);
  EXPECT_NE(r.status().message().find("/nonexistent/dir/path.cam"), std::string::npos);
}

TEST(CameraPath, UnwritableFileIsIoError) {
  const Status st = write_camera_path("/nonexistent/dir/path.cam", sample_frames());
  ASSERT_FALSE(st.is_ok());
  EXPECT_EQ(st.code(), Status::Code::IoError);
}

}  // namespace
}  // namespace frontier
