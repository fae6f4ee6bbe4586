#include "stipple/renderer/png.hpp"

#include <png.h>

#include <cstdio>
#include <memory>

#include "stipple/core/atomic_file.hpp"
#include "stipple/core/error.hpp"

namespace stipple::gpu {

void write_png(const std::filesystem::path& path, const Image& image) {
  if (image.rgba.size() != size_t(image.width) * image.height * 4)
    fail("{}: image data does not match its size", path.string());
  AtomicFile file(path);
  png_image png{};
  png.version = PNG_IMAGE_VERSION;
  png.width = image.width;
  png.height = image.height;
  png.format = PNG_FORMAT_RGBA;
  if (!png_image_write_to_file(&png, file.temp_path().c_str(), 0, image.rgba.data(), 0, nullptr))
    fail("{}: cannot write PNG: {}", path.string(), png.message);
  file.commit();
}

Image read_png(const std::filesystem::path& path) {
  png_image png{};
  png.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&png, path.c_str()))
    fail("{}: cannot read PNG: {}", path.string(), png.message);
  png.format = PNG_FORMAT_RGBA;
  Image image{png.width, png.height, std::vector<uint8_t>(PNG_IMAGE_SIZE(png))};
  if (!png_image_finish_read(&png, nullptr, image.rgba.data(), 0, nullptr))
    fail("{}: cannot read PNG: {}", path.string(), png.message);
  return image;
}

}  // namespace stipple::gpu
