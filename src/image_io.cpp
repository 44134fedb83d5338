#include "fillgs/image_io.hpp"

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "fillgs/error.hpp"
#include "fillgs/limits.hpp"
#include "fillgs/fs_util.hpp"

namespace fillgs {

void write_image(const std::string& path, const Image& img) {
  FILLGS_CHECK_EQ(img.pixels.size(), size_t(img.width) * img.height * img.channels);
  const std::string ext = std::filesystem::path(path).extension().string();
  const bool is_float = ext == ".exr" || ext == ".hdr" || ext == ".tif" || ext == ".tiff";
  write_atomically(path, [&](const std::string& tmp) {
    auto out = OIIO::ImageOutput::create(tmp);
    if (!out) throw_error(path, ": cannot create image writer (", OIIO::geterror(), ")");
    OIIO::ImageSpec spec(img.width, img.height, img.channels, is_float ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::UINT8);
    if (!out->open(tmp, spec)) throw_error(path, ": cannot open for writing (", out->geterror(), ")");
    bool ok;
    if (is_float) {
      ok = out->write_image(OIIO::TypeDesc::FLOAT, img.pixels.data());
    } else {
      std::vector<unsigned char> bytes(img.pixels.size());
      for (size_t i = 0; i < bytes.size(); ++i) {
        const float v = img.pixels[i];
        const float c = std::isfinite(v) ? std::clamp(v, 0.0f, 1.0f) : 0.0f;
        bytes[i] = static_cast<unsigned char>(c * 255.0f + 0.5f);
      }
      ok = out->write_image(OIIO::TypeDesc::UINT8, bytes.data());
    }
    if (!ok || !out->close()) throw_error(path, ": write failed (", out->geterror(), ")");
  });
}

Image read_image(const std::string& path) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) throw_error(path, ": cannot read image (", OIIO::geterror(), ")");
  const OIIO::ImageSpec& spec = in->spec();
  // The size is the file's word: checked before the pixels are allocated.
  image_side(spec.width, path, "the image", "width");
  image_side(spec.height, path, "the image", "height");
  if (spec.nchannels < 1 || spec.nchannels > 64) throw_error(path, ": image claims ", spec.nchannels, " channels (1..64)");
  check_allocation(size_t(spec.width) * size_t(spec.height) * size_t(spec.nchannels) * sizeof(float), path,
                   "an image of " + std::to_string(spec.width) + "x" + std::to_string(spec.height));
  Image img(spec.width, spec.height, spec.nchannels);
  if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, img.pixels.data()))
    throw_error(path, ": cannot decode image (", in->geterror(), ")");
  in->close();
  return img;
}

bool image_size(const std::string& path, int* width, int* height) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) return false;
  auto in = OIIO::ImageInput::open(path);
  if (!in) {
    (void)OIIO::geterror();
    return false;
  }
  *width = in->spec().width;
  *height = in->spec().height;
  in->close();
  return true;
}

}  // namespace fillgs
