#include "fillgs/io/image_io.hpp"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cmath>
#include <cctype>
#include <filesystem>
#include <fstream>
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

double Image::bilinear(double u, double v, int c) const {
  const int i0 = std::min(int(u), std::max(0, width - 2)), j0 = std::min(int(v), std::max(0, height - 2));
  const int i1 = std::min(i0 + 1, width - 1), j1 = std::min(j0 + 1, height - 1);
  const double a = std::clamp(u - i0, 0.0, 1.0), b = std::clamp(v - j0, 0.0, 1.0);
  auto px = [&](int i, int j) { return double(pixels[(size_t(j) * width + size_t(i)) * size_t(channels) + size_t(c)]); };
  return (1 - a) * (1 - b) * px(i0, j0) + a * (1 - b) * px(i1, j0) + (1 - a) * b * px(i0, j1) + a * b * px(i1, j1);
}

Image rgb_channels(const Image& image, const std::string& what) {
  if (image.channels < 3) throw_error(what, " has ", image.channels, " channels, expected RGB");
  if (image.channels == 3) return image;
  Image rgb(image.width, image.height, 3);
  for (size_t p = 0; p < size_t(image.width) * size_t(image.height); ++p)
    for (int c = 0; c < 3; ++c) rgb.pixels[p * 3 + size_t(c)] = image.pixels[p * size_t(image.channels) + size_t(c)];
  return rgb;
}

Image read_rgb_image(const std::string& path, int width, int height) {
  const Image im = read_image(path);
  if (im.width != width || im.height != height || im.channels < 3)
    throw_error(path, ": not a ", width, "x", height, " RGB image (", im.width, "x", im.height, ", ", im.channels, " channels)");
  return rgb_channels(im, path);
}

void write_image(const std::string& path, const Image& img) {
  FILLGS_CHECK_EQ(img.pixels.size(), size_t(img.width) * img.height * img.channels);
  const std::string ext = std::filesystem::path(path).extension().string();
  const bool is_float = ext == ".exr" || ext == ".hdr" || ext == ".tif" || ext == ".tiff";
  write_atomically(path, [&](const std::string& tmp) {
    auto out = OIIO::ImageOutput::create(tmp);
    if (!out) throw_error(path, ": cannot create image writer (", OIIO::geterror(), ")");
    OIIO::ImageSpec spec(img.width, img.height, img.channels, is_float ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::UINT8);
    // The image is encoded in memory and its bytes written by fillgs, which checks every
    // write: an encoder's own file writes (libpng's) do not report a full disk or a file-size
    // limit, and would leave a truncated image that looks written.
    OIIO::Filesystem::IOVecOutput memory;
    const bool in_memory = out->supports("ioproxy") && out->set_ioproxy(&memory);
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
    if (in_memory) write_file_checked(tmp, path, memory.buffer().data(), memory.buffer().size());
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
  std::error_code ec;
  if (std::filesystem::exists(path, ec) && !std::filesystem::is_regular_file(path, ec)) {
    *why = "not a regular file";  // a named pipe would hang the reader
    return nullptr;
  }
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

namespace {

/// True when the JPEG at `path` has an end-of-image marker (FF D9) in its last megabyte: a
/// marker cannot occur inside entropy-coded data (0xFF is stuffed there), and data may
/// follow it (appended thumbnails, metadata).
bool has_jpeg_end(const std::string& path) {
  std::ifstream f(path, std::ios::binary | std::ios::ate);
  const std::streamoff size = f.tellg();
  if (!f || size < 4) return false;
  const std::streamoff tail = std::min<std::streamoff>(size, 1 << 20);
  std::string bytes(size_t(tail), '\0');
  f.seekg(size - tail);
  f.read(bytes.data(), tail);
  for (size_t i = bytes.size() - 1; i > 0; --i)
    if (static_cast<unsigned char>(bytes[i - 1]) == 0xFF && static_cast<unsigned char>(bytes[i]) == 0xD9) return true;
  return false;
}

}  // namespace

Image read_image(const std::string& path) {
  require_regular_file(path);  // a pipe would hang the decoder; a folder a killed commit left mixed is refused
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
  // libjpeg decodes a JPEG cut short as grey from where the data ends, with a warning no
  // caller sees: a JPEG must hold its end-of-image marker.
  if (std::string(in->format_name()) == "jpeg" && !has_jpeg_end(path)) throw_error(path, ": the JPEG is cut short (no end-of-image marker)");
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
