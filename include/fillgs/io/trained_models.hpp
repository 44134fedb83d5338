#pragma once
// The 4D models users train with the field's codebases, read as their training code saves
// them and evaluated at any time exactly as their renderers do:
//
//  * E-D3DGS (the FillGS paper's backbone): point_cloud.ply with per-Gaussian embeddings,
//    deformation.pth (temporal embeddings, per-camera time offsets, a coarse and a fine MLP),
//    cfg_args;
//  * 4DGaussians: point_cloud.ply, deformation.pth (HexPlane feature planes, MLP heads),
//    cfg_args;
//  * 4D Gaussian Splatting (Yang et al.): chkpnt*.pth (4D means, scales, two quaternions,
//    time mean and scale, SH with time terms), sliced in time in closed form;
//  * Deformable 3D Gaussians: point_cloud.ply, deform/iteration_N/deform.pth (an MLP on
//    encoded position and time), cfg_args;
//  * Dynamic 3D Gaussians: params.npz (per-frame means, colours, rotations);
//  * a folder of per-frame 3DGS PLYs (4DGaussians' export_perframe_3DGS.py, viewer sequences).
//
// A model is sampled at each of its frames into fillgs's keyframed tracks (one key per
// frame: position, rotation, scale, opacity, colour), so every command takes it like any
// other scene; between frames fillgs interpolates. data/README.md lists what each format
// needs and what is approximated.
#include <memory>
#include <string>
#include <vector>

#include "fillgs/base/math.hpp"
#include "fillgs/io/scene_io.hpp"
#include "fillgs/model/gaussians.hpp"

namespace fillgs {

/// The Gaussians a trained model gives at one model time: raw values (log-scales,
/// unnormalised quaternions, opacity logits, SH), as its renderer hands them to the rasteriser.
struct ModelState {
  int sh_degree = 0;
  std::vector<Vec3f> means, log_scales;
  std::vector<Vec4f> rotations;
  std::vector<float> opacity_logits;
  std::vector<float> opacity_factor;  ///< a temporal factor applied after the sigmoid (4DGS); empty: 1
  std::vector<float> sh;              ///< [N][(degree+1)^2][3]
  size_t size() const { return means.size(); }
};

class TrainedModel {
 public:
  virtual ~TrainedModel() = default;
  virtual size_t size() const = 0;
  /// The Gaussians at model time `model_time` (the training code's own time value).
  virtual ModelState at(double model_time) const = 0;

  SceneFormat format = SceneFormat::Auto;
  std::string source;
  int frames = 0;                ///< frames the model covers
  double time_first = 0.0;       ///< model time of frame 0
  double time_last = 0.0;        ///< model time of frame frames-1
  std::vector<std::string> notes;

  /// Model time of (fractional) frame f.
  double frame_time(double f) const {
    return frames > 1 ? time_first + (time_last - time_first) * f / double(frames - 1) : time_first;
  }
};

/// Opens a trained model of one of the formats above (`format` must be one of them).
std::unique_ptr<TrainedModel> open_trained_model(const std::string& path, SceneFormat format, const SceneReadOptions& options);

/// The model sampled at each of its frames into keyframed tracks, one key per frame
/// (t_f = f / (frames - 1)); SH bands above the DC keep their mean over the frames.
GaussianCloud sample_trained_model(const TrainedModel& model);

/// The format of a directory or file holding one of the models above, or Auto if none.
SceneFormat detect_trained_model(const std::string& path);

/// Throws one line if `ply` is the canonical PLY of a deformation model (embedding_*
/// properties, or deformation.pth / deform/ beside it), saying what to pass instead.
void refuse_canonical_ply(const std::string& ply, const std::string& header);

/// A Python literal (what cfg_args holds: Namespace(key=value, ...)) as JSON; exposed for tests.
std::string python_literal_to_json(const std::string& text, const std::string& source);

}  // namespace fillgs
