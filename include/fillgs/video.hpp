#pragma once
// Multi-view video as distributed (Neural 3D Video: a folder of camNN.mp4 and
// poses_bounds.npy), decoded with OpenCV's VideoCapture (FFmpeg in Debian). Frames are
// decoded in order, once, and only the ones asked for are kept (8-bit, block-averaged).
#include <cstdint>
#include <string>
#include <vector>

namespace fillgs {

/// The .mp4 files of a folder, sorted by name (the order of poses_bounds.npy's rows).
std::vector<std::string> videos_in(const std::string& folder);

/// Frames and size a video's container reports; one clear error if it cannot be opened.
struct VideoInfo {
  int frames = 0, width = 0, height = 0;
};
VideoInfo probe_video(const std::string& path);

/// Decodes `path` in order and returns, for each frame index in `frames` (increasing), its
/// RGB pixels averaged over k×k blocks ([H/k][W/k][3], 8-bit). Every frame must decode and
/// be width × height; otherwise one error naming the file and the frame.
std::vector<std::vector<uint8_t>> decode_video_frames(const std::string& path, const std::vector<int>& frames, int k, int width, int height);

/// `k`×k block average of interleaved 8-bit or float pixels (the last W mod k columns and
/// H mod k rows dropped), to 8-bit; `source_channels` ≥ `channels`, channel order by `order`
/// (e.g. {2, 1, 0} for BGR → RGB).
std::vector<uint8_t> block_average_u8(const uint8_t* src, int width, int height, int source_channels, int channels, const int* order, int k);

}  // namespace fillgs
