#pragma once
// Image files through OpenImageIO. Images are float, row-major, interleaved channels.
#include <string>
#include <vector>

namespace fillgs {

struct Image {
  int width = 0, height = 0, channels = 0;
  std::vector<float> pixels;  ///< [height][width][channels]
  Image() = default;
  Image(int w, int h, int c, float fill = 0.0f) : width(w), height(h), channels(c), pixels(size_t(w) * h * c, fill) {}
  /// Takes pixels already laid out [h][w][c] (a render's `rgb`, a dataset's image); a size
  /// that is not w·h·c is a one-line error.
  Image(int w, int h, int c, std::vector<float> data);
  float& at(int x, int y, int c) { return pixels[(size_t(y) * width + x) * channels + c]; }
  float at(int x, int y, int c) const { return pixels[(size_t(y) * width + x) * channels + c]; }
  /// Channel c bilinearly interpolated at pixel-index coordinates (u, v) (pixel i's centre
  /// at i), clamped to the image.
  double bilinear(double u, double v, int c) const;
};

/// The first three channels of an image (alpha and the rest dropped); fewer than three is
/// a one-line error naming `what`.
Image rgb_channels(const Image& image, const std::string& what);

/// Reads `path` as an RGB image of exactly width × height (extra channels dropped); anything
/// else is a one-line error naming the file.
Image read_rgb_image(const std::string& path, int width, int height);

/// Writes an image atomically. `.png`/`.jpg`: 8-bit, values clamped to [0, 1], no gamma
/// (like the original 3DGS); `.exr`: 32-bit float, values as they are.
void write_image(const std::string& path, const Image& image);

/// Reads an image as float in [0, 1] (8/16-bit) or as stored (float formats).
Image read_image(const std::string& path);

/// Size of an image file without reading its pixels; false if it cannot be opened.
bool image_size(const std::string& path, int* width, int* height);

}  // namespace fillgs
