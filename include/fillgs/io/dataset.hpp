#pragma once
// Multi-view video as training and evaluation read it: the views (a camera at a frame
// time), their 8-bit images (in memory or in the image cache, pixel_store.hpp) and
// foreground masks, with the frame range, downscaling and monocular cycling users ask for.
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "fillgs/base/progress.hpp"
#include "fillgs/io/camera_io.hpp"
#include "fillgs/model/camera.hpp"
#include "fillgs/io/pixel_store.hpp"

namespace fillgs {

/// One training image: a camera at a frame time.
struct TrainView {
  Camera camera;           ///< with time t = frame / (frames − 1)
  std::string image_path;  ///< resolved file
  std::string rig;         ///< camera of the rig ("cam00")
  int frame = 0;
  int source_frame = 0;    ///< the frame in the source (folder, meta file or video) before --frames
};

/// Frames first, first + step, … before last (last < 0: to the end), as Python's
/// first:last:step. The chosen frames become the video: frame j of n at t = j / (n − 1).
struct FrameRange {
  int first = 0, last = -1, step = 1;
  bool all() const { return first == 0 && last < 0 && step == 1; }
  /// "first:last:step", "first:last" or "first:" ("" or ":" = all frames).
  static FrameRange parse(const std::string& text);
};

struct DatasetOptions {
  /// Rig cameras to train on (names as in the camera file, e.g. "cam00"); empty: all.
  std::vector<std::string> cameras;
  /// Single photographs added to `cameras` (which must then be given): a camera at one frame,
  /// the frame numbered as `frames` leaves them — the camera-times a pool selection chose
  /// (finetune's pool_chosen.json). A camera also in `cameras` keeps every frame.
  std::vector<std::pair<std::string, int>> camera_times;
  FrameRange frames;
  /// Images averaged over k×k blocks (the last W mod k columns and H mod k rows dropped) and
  /// cameras scaled to match: fx, fy, cx, cy / k.
  int downscale = 1;
  /// Monocular video from a multi-view one (the paper's protocol for the Nvidia scenes):
  /// frame f (after `frames`) keeps only the view of camera cycle[f mod n]. Empty: all views.
  std::vector<std::string> monocular_cycle;
  /// Bytes of 8-bit images held in memory (< 0: default_image_budget(), a quarter of the
  /// machine's memory); a dataset with more is kept in an unlinked temporary file in
  /// `spill_dir` (empty: $TMPDIR or /tmp) and each image read back when it is used.
  int64_t image_memory = -1;
  std::string spill_dir;
  /// A camera file of held-out cameras (any format read_cameras reads): a view standing
  /// where one of them stands (centres within held_out_distance world units, viewing
  /// rotations within held_out_degrees) is refused before any image is read, so a held-out
  /// camera's images never reach training, a pool or a selection. Empty: none. The defaults
  /// (1e-3 units, 0.1 degrees) take a camera file rounded to five decimals for the camera it
  /// rounds (1e-5 off), and stay far below the spacing of any capture rig (centimetres and
  /// degrees apart).
  std::string held_out;
  double held_out_distance = 1e-3;
  double held_out_degrees = 0.1;
};

/// Multi-view video. Two layouts:
///  * cameras with times and image paths (transforms.json with `time`, fillgs synth output):
///    one view per entry; the image is looked up under the images folder by its path
///    (a leading "images/" may be dropped), then beside the camera file;
///  * a rig without times (COLMAP, transforms without `time`, ...): `images/<camera>/<frame>.png`,
///    frames sorted by name, frame f at t = f / (F − 1); a single frame as `images/<camera>.png`
///    (or .jpg); Technicolor's `<Scene>_undist_<frame>_<NN>.png` for camera camNN; or, where the folder holds
///    `<camera>.mp4` instead (Neural 3D Video as distributed), the video's frames, decoded
///    once with FFmpeg (video.hpp). With poses_bounds.npy, its rows name the folder's videos
///    in sorted order (cam00.mp4 … as they are; a scene that lacks a camera keeps the names
///    of the ones it has). Every video needs the camera's size and the same frame count.
/// Every image must exist and match its camera's size. Images are cached as 8-bit RGB.
/// Foreground masks (Dynamic 3D Gaussians' layout): when a `seg/` folder stands beside the
/// camera file, every image needs `seg/<its path under the images folder, as .png>`; a pixel
/// is foreground where the mask is above one half. Evaluation uses them as the moving region
/// when no ground-truth scene is given.
class Dataset {
 public:
  /// `progress` counts the images (video frames included) as they are decoded.
  static Dataset load(const std::string& images_dir, const std::string& cameras_path, const DatasetOptions& options = {},
                      Progress& progress = null_progress());

  const std::vector<TrainView>& views() const { return views_; }
  const std::vector<std::string>& rigs() const { return rigs_; }
  int frames() const { return frames_; }
  /// Frames of the source video before DatasetOptions::frames chose some (TrainView::source_frame
  /// counts in it).
  int source_frames() const { return source_frames_ ? source_frames_ : frames_; }
  bool has_masks() const { return !masks_.empty(); }
  /// The view's foreground mask, 1 = foreground ([H][W]); empty without masks.
  std::vector<uint8_t> mask(size_t view) const { return masks_.empty() ? std::vector<uint8_t>() : masks_.at(view); }
  /// The view's image as float RGB in [0, 1] ([H][W][3]).
  std::vector<float> image(size_t view) const;
  /// The view's image as held, 8-bit RGB ([H][W][3]; image() is it / 255), handed over: the
  /// dataset no longer holds it (for a caller done with the dataset, such as Python's
  /// load_views, so that the images are never in memory twice).
  std::vector<uint8_t> take_image8(size_t view);
  /// Bytes of the 8-bit images, and whether they are kept on disk (DatasetOptions::image_memory).
  size_t image_bytes() const { return pixels_.bytes(); }
  bool images_spilled() const { return pixels_.spilled(); }
  /// Centre and radius of the camera centres ×1.1 (3DGS "cameras_extent").
  std::pair<Vec3f, float> camera_extent() const;

 private:
  std::vector<TrainView> views_;
  std::vector<std::string> rigs_;
  int frames_ = 1;
  int source_frames_ = 0;  ///< 0: frames_ (no frame range applied)
  PixelStore pixels_;
  std::vector<std::vector<uint8_t>> masks_;
  /// Keeps the views of the frames `range` chooses, renumbered with their times; `per_view`
  /// is filtered alike.
  void keep_frames(const FrameRange& range, std::vector<std::string>* per_view, const std::string& source);
  /// Keeps the views of `cameras` and the single `camera_times`.
  void keep_camera_times(const DatasetOptions& options, std::vector<std::string>* per_view, const std::string& source);
  /// Keeps, per frame f, only the view of camera cycle[f mod n].
  void keep_cycle(const std::vector<std::string>& cycle, std::vector<std::string>* per_view, const std::string& source);
};

}  // namespace fillgs
