// PNG and id-image files.
#include "src/io/image.h"

#include <png.h>

#include <cstdio>
#include <cstring>
#include <memory>

namespace frontier {

namespace {

struct FileCloser {
  void operator()(FILE* f) const { if (f) std::fclose(f); }
};

}  // namespace

Status write_png(const std::string& path, int width, int height, const std::vector<Rgb>& pixels) {
  if (width <= 0 || height <= 0 || pixels.size() != size_t(width) * size_t(height)) {
    return Status::invalid_argument(path + ": image size does not match its pixels");
  }
  std::unique_ptr<FILE, FileCloser> file(std::fopen(path.c_str(), "wb"));
  if (!file) return Status::io_error(path + ": cannot open for writing: " + std::strerror(errno));
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (!png || !info) {
    png_destroy_write_struct(&png, &info);
    return Status::io_error(path + ": libpng initialisation failed");
  }
  std::vector<uint8_t> row(size_t(width) * 3);
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    return Status::io_error(path + ": PNG write failed");
  }
  png_init_io(png, file.get());
  png_set_IHDR(png, info, uint32_t(width), uint32_t(height), 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  auto to8 = [](float v) {
    const float c = v < 0.0f ? 0.0f : (v > 1.0f ? 1.0f : v);
    return static_cast<uint8_t>(c * 255.0f + 0.5f);
  };
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const Rgb& p = pixels[size_t(y) * size_t(width) + size_t(x)];
      row[size_t(x) * 3 + 0] = to8(p.r);
      row[size_t(x) * 3 + 1] = to8(p.g);
      row[size_t(x) * 3 + 2] = to8(p.b);
    }
    png_write_row(png, row.data());
  }
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  if (std::fflush(file.get()) != 0) return Status::io_error(path + ": write failed");
  return Status::ok();
}

Status read_png(const std::string& path, int& width, int& height, std::vector<Rgb>& pixels) {
  png_image image;
  std::memset(&image, 0, sizeof(image));
  image.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&image, path.c_str())) {
    return Status::io_error(path + ": cannot read PNG: " + image.message);
  }
  image.format = PNG_FORMAT_RGB;
  std::vector<uint8_t> data(PNG_IMAGE_SIZE(image));
  if (!png_image_finish_read(&image, nullptr, data.data(), 0, nullptr)) {
    png_image_free(&image);
    return Status::corruption(path + ": bad PNG: " + image.message);
  }
  width = int(image.width);
  height = int(image.height);
  pixels.resize(size_t(width) * size_t(height));
  for (size_t i = 0; i < pixels.size(); ++i) {
    pixels[i] = {data[3 * i] / 255.0f, data[3 * i + 1] / 255.0f, data[3 * i + 2] / 255.0f};
  }
  return Status::ok();
}

Status write_ids(const std::string& path, const std::vector<uint32_t>& ids) {
  std::unique_ptr<FILE, FileCloser> file(std::fopen(path.c_str(), "wb"));
  if (!file) return Status::io_error(path + ": cannot open for writing: " + std::strerror(errno));
  std::vector<uint8_t> bytes(ids.size() * 4);
  for (size_t i = 0; i < ids.size(); ++i) {
    for (int b = 0; b < 4; ++b) bytes[4 * i + size_t(b)] = uint8_t(ids[i] >> (8 * b));
  }
  if (std::fwrite(bytes.data(), 1, bytes.size(), file.get()) != bytes.size() || std::fflush(file.get()) != 0) {
    return Status::io_error(path + ": write failed");
  }
  return Status::ok();
}

}  // namespace frontier
