// PNG output and input through libpng: atomic writes (temporary name, then rename), simplified-API reads.
#include <png.h>

#include <cerrno>
#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#include "render/writers.hpp"

namespace lumen::render {

namespace {

// libpng error text for the write below; the error callback fills it and longjmps out.
struct PngError {
  char message[256] = {0};
};

void png_error_to_buffer(png_structp png, png_const_charp text) {
  auto* err = static_cast<PngError*>(png_get_error_ptr(png));
  std::snprintf(err->message, sizeof(err->message), "%s", text);
  png_longjmp(png, 1);
}

void png_warning_ignored(png_structp, png_const_charp) {}

// Encodes rows into an open FILE. Only trivially destructible objects live in this frame, so the
// longjmp from libpng's error handler skips no destructor. Returns false with err.message set on error.
bool encode_png(std::FILE* file, int width, int height, png_bytepp rows, PngError& err) {
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &err, png_error_to_buffer, png_warning_ignored);
  if (png == nullptr) {
    std::snprintf(err.message, sizeof(err.message), "png_create_write_struct failed");
    return false;
  }
  png_infop info = png_create_info_struct(png);
  if (info == nullptr) {
    png_destroy_write_struct(&png, nullptr);
    std::snprintf(err.message, sizeof(err.message), "png_create_info_struct failed");
    return false;
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    return false;
  }
  png_init_io(png, file);
  // Speed over size: zlib level 1 with the Sub filter (measured in bench_render: a few ms at 640x480).
  png_set_compression_level(png, 1);
  png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_SUB);
  png_set_IHDR(png, info, static_cast<png_uint_32>(width), static_cast<png_uint_32>(height), 8, PNG_COLOR_TYPE_RGB,
               PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  png_write_image(png, rows);
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return true;
}

}  // namespace

void write_png(const std::string& path, const Image& image) {
  // Validate the image at the boundary.
  if (image.width <= 0 || image.height <= 0)
    throw std::invalid_argument("write_png(" + path + "): image size must be positive (value " + std::to_string(image.width) + "x" +
                                std::to_string(image.height) + ")");
  const size_t expected = static_cast<size_t>(image.width) * image.height * 3;
  if (image.rgb.size() != expected)
    throw std::invalid_argument("write_png(" + path + "): image.rgb has " + std::to_string(image.rgb.size()) + " bytes, expected " +
                                std::to_string(expected));

  // Encode into path.tmp, then rename onto the final name; on any failure remove the temporary.
  const std::string tmp = path + ".tmp";
  std::FILE* file = std::fopen(tmp.c_str(), "wb");
  if (file == nullptr) throw std::runtime_error("write_png: cannot create " + tmp + " for " + path + ": " + std::strerror(errno));
  std::vector<png_bytep> rows(image.height);
  for (int y = 0; y < image.height; ++y) rows[y] = const_cast<png_bytep>(&image.rgb[static_cast<size_t>(y) * image.width * 3]);
  PngError err;
  const bool encoded = encode_png(file, image.width, image.height, rows.data(), err);
  const bool flushed = std::fflush(file) == 0 && std::ferror(file) == 0;
  const int flush_errno = errno;
  const bool closed = std::fclose(file) == 0;
  std::string problem;
  if (!encoded) {
    problem = std::string("libpng: ") + err.message;
  } else if (!flushed || !closed) {
    problem = std::string("write failed: ") + std::strerror(flushed ? errno : flush_errno);
  } else if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    problem = std::string("rename from ") + tmp + " failed: " + std::strerror(errno);
  }
  if (!problem.empty()) {
    std::remove(tmp.c_str());
    throw std::runtime_error("write_png(" + path + "): " + problem);
  }
}

Image read_png(const std::string& path) {
  // libpng's simplified API: any 8-bit PNG converted to RGB (alpha composited away).
  png_image img;
  std::memset(&img, 0, sizeof(img));
  img.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&img, path.c_str())) {
    throw std::runtime_error("read_png(" + path + "): " + img.message);
  }
  img.format = PNG_FORMAT_RGB;
  Image out;
  out.width = static_cast<int>(img.width);
  out.height = static_cast<int>(img.height);
  out.rgb.resize(PNG_IMAGE_SIZE(img));
  if (!png_image_finish_read(&img, nullptr, out.rgb.data(), 0, nullptr)) {
    const std::string message = img.message;
    png_image_free(&img);
    throw std::runtime_error("read_png(" + path + "): " + message);
  }
  return out;
}

}  // namespace lumen::render
