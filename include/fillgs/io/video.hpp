#pragma once
// Multi-view video as distributed (Neural 3D Video: a folder of camNN.mp4 and
// poses_bounds.npy), decoded with OpenCV's VideoCapture (FFmpeg in Debian). Frames are
// decoded in order, once, and only the ones asked for are kept (8-bit, block-averaged).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "fillgs/base/error.hpp"

namespace fillgs {

/// The .mp4 files of a folder, sorted by name (the order of poses_bounds.npy's rows).
std::vector<std::string> videos_in(const std::string& folder);

/// Frames and size a video's container reports; one clear error if it cannot be opened.
struct VideoInfo {
  int frames = 0, width = 0, height = 0;
};
VideoInfo probe_video(const std::string& path);

/// Decodes `path` in order and hands, for each frame index in `frames` (increasing), its
/// RGB pixels averaged over k×k blocks ([H/k][W/k][3], 8-bit) to `sink(index into frames,
/// pixels)` as soon as it is decoded, so that no more than one frame is held. Every frame
/// must decode and be width × height; otherwise one error naming the file and the frame.
void decode_video_frames(const std::string& path, const std::vector<int>& frames, int k, int width, int height,
                         const std::function<void(size_t, std::vector<uint8_t>&&)>& sink);

/// `k`×k block average of interleaved pixels (the last W mod k columns and H mod k rows
/// dropped) to 8-bit: each sample × `to_255` (255 for floats in [0, 1], 1 for 8-bit),
/// clamped to [0, 255]; `source_channels` ≥ `channels`, channel c read from `order[c]`
/// (e.g. {2, 1, 0} for BGR → RGB).
template <typename T>
std::vector<uint8_t> block_average_u8(const T* src, int width, int height, int source_channels, int channels, const int* order, int k,
                                      float to_255) {
  const int W = width / k, H = height / k;
  if (W < 1 || H < 1) throw_error("downscale ", k, " leaves no pixel of a ", width, "x", height, " image");
  std::vector<uint8_t> out(size_t(W) * size_t(H) * size_t(channels));
  const float norm = 1.0f / float(k * k);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x)
      for (int c = 0; c < channels; ++c) {
        float sum = 0;
        for (int dy = 0; dy < k; ++dy)
          for (int dx = 0; dx < k; ++dx) {
            const float v = float(src[(size_t(y * k + dy) * size_t(width) + size_t(x * k + dx)) * size_t(source_channels) + size_t(order[c])]);
            sum += std::clamp(v * to_255, 0.0f, 255.0f);
          }
        out[(size_t(y) * size_t(W) + size_t(x)) * size_t(channels) + size_t(c)] = uint8_t(std::lround(sum * norm));
      }
  return out;
}

}  // namespace fillgs
