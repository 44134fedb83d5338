#include "fillgs/io/image_io.hpp"

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cmath>
#include <cctype>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "fillgs/base/error.hpp"
#include "fillgs/base/limits.hpp"
#include "fillgs/base/fs_util.hpp"

namespace fillgs {

Image::Image(int w, int h, int c, std::vector<float> data) : width(w), height(h), channels(c), pixels(std::move(data)) {
  if (w < 0 || h < 0 || c < 0 || pixels.size() != size_t(w) * size_t(h) * size_t(c))
    throw_error("image: ", pixels.size(), " values for ", w, "x", h, "x", c);
}

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

namespace {

/// OpenImageIO's messages can span lines; fillgs's errors are one line.
std::string one_line(std::string text) {
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
  for (size_t at = text.find('\n'); at != std::string::npos; at = text.find('\n', at)) text.replace(at, 1, "; ");
  return text;
}

/// The extension of `path`, lower case without the dot, when OpenImageIO has a reader for it
/// ("png", "jpg", "exr"); empty otherwise.
std::string image_extension(const std::string& path) {
  static const std::vector<std::string> known = [] {
    std::vector<std::string> out;
    for (const auto& [format, extensions] : OIIO::get_extension_map()) out.insert(out.end(), extensions.begin(), extensions.end());
    return out;
  }();
  std::string ext = std::filesystem::path(path).extension().string();
  if (ext.empty()) return ext;
  ext.erase(0, 1);
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return std::find(known.begin(), known.end(), ext) != known.end() ? ext : std::string();
}

/// Opens `path` with the reader its extension names (a `.png` is read as PNG or not at all);
/// only a name without a known image extension makes OpenImageIO try every reader in turn.
/// Trying them all on a damaged PNG is slow and hands it to readers that trust it more
/// (WebP's allocates ~450 MB for a 44-byte input). Null with `why` set when it cannot.
std::unique_ptr<OIIO::ImageInput> open_image(const std::string& path, std::string* why) {
  const std::string ext = image_extension(path);
  // create() given a format name (not the file's) makes that reader and no other.
  std::unique_ptr<OIIO::ImageInput> in = ext.empty() ? OIIO::ImageInput::open(path) : OIIO::ImageInput::create(ext);
  if (!in) {
    *why = one_line(OIIO::geterror());
    return nullptr;
  }
  if (ext.empty()) return in;
  OIIO::ImageSpec spec;
  if (in->open(path, spec)) return in;
  *why = std::string("not a readable ") + in->format_name() + " file: " + one_line(in->geterror());
  return nullptr;
}

}  // namespace

Image read_image(const std::string& path) {
  std::string why;
  auto in = open_image(path, &why);
  if (!in) throw_error(path, ": cannot read image (", why, ")");
  const OIIO::ImageSpec& spec = in->spec();
  // The size is the file's word: checked before the pixels are allocated.
  image_side(spec.width, path, "the image", "width");
  image_side(spec.height, path, "the image", "height");
  if (spec.nchannels < 1 || spec.nchannels > 64) throw_error(path, ": image claims ", spec.nchannels, " channels (1..64)");
  check_allocation(size_t(spec.width) * size_t(spec.height) * size_t(spec.nchannels) * sizeof(float), path,
                   "an image of " + std::to_string(spec.width) + "x" + std::to_string(spec.height));
  Image img(spec.width, spec.height, spec.nchannels);
  if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, img.pixels.data()))
    throw_error(path, ": cannot decode image (", one_line(in->geterror()), ")");
  in->close();
  return img;
}

bool image_size(const std::string& path, int* width, int* height) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) return false;
  std::string why;
  auto in = open_image(path, &why);
  if (!in) return false;
  *width = in->spec().width;
  *height = in->spec().height;
  in->close();
  return true;
}

}  // namespace fillgs
