#pragma once
// The splat rasterizer (forward): a tile-based CPU renderer with the exact math of the
// original 3DGS CUDA rasterizer (graphdeco-inria diff-gaussian-rasterization, forward.cu):
//  * EWA projection, Jacobian clamp at 1.3·tan(fov/2), +0.3 on the 2D covariance diagonal;
//  * radius ceil(3·sqrt(λmax)), 16×16 tiles, per-tile front-to-back order by view depth;
//  * α = min(0.99, o·exp(-½ dᵀΣ⁻¹d)), skipped below 1/255, stop before T drops under 1e-4;
//  * pixel centres at integer coordinates of the 3DGS image plane (x_pix = fx·x/z + cx − ½).
// Any per-Gaussian feature can be blended like colour. Threads over tiles (TBB); the result
// does not depend on the thread count, bit for bit.
#include <cstdint>
#include <string>
#include <vector>

#include "fillgs/base/names.hpp"
#include "fillgs/model/camera.hpp"
#include "fillgs/model/gaussians.hpp"

namespace fillgs {

constexpr int kTileSize = 16;
constexpr float kMinAlpha = 1.0f / 255.0f;
constexpr float kMaxAlpha = 0.99f;
constexpr float kMinTransmittance = 1e-4f;
constexpr float kNearPlane = 0.2f;
constexpr float kDilation = 0.3f;

/// Which implementation of the tile kernel blends (src/render/tile_kernel.hpp): the vector
/// one (Google Highway, the instruction set chosen at run time) or the scalar reference it
/// is measured and tested against. `Default` follows set_default_kernel() (the CLI's
/// `--kernel`, initially Simd). Double-precision rendering is always scalar.
enum class Kernel : uint8_t { Default, Simd, Scalar };
void set_default_kernel(Kernel kernel);  ///< Default is not a valid argument
Kernel resolve_kernel(Kernel kernel);    ///< Default → the process default
FILLGS_ENUM_NAMES(Kernel, "kernel", {Kernel::Simd, "simd"}, {Kernel::Scalar, "scalar"});
const char* kernel_name(Kernel kernel);        ///< "simd" | "scalar" (Default resolved)
/// The instruction set the vector kernel uses on this machine (e.g. "AVX3", "AVX2").
const char* simd_target();
/// Floats per vector instruction of the vector kernel on this machine (16 with AVX-512).
int simd_lanes();

/// A Gaussian's screen-space footprint, as the 3DGS preprocess computes it.
struct ProjectedGaussian {
  Vec2f mean;       ///< pixel coordinates (3DGS convention: pixel i has centre i)
  Vec3f conic;      ///< inverse of the dilated 2D covariance (a, b, c) for [[a b][b c]]
  Vec3f cov2d;      ///< dilated 2D covariance (a, b, c)
  float depth = 0;  ///< view-space z
  int radius = 0;   ///< ceil(3 sqrt(λmax)); 0 = not rendered ("radii > 0" semantics)
  int rect_min[2] = {0, 0}, rect_max[2] = {0, 0};  ///< touched tiles, [min, max)
};

/// Projects one Gaussian (scale = exp(log-scale), unit rotation) into a camera.
/// Returns false (radius 0) when 3DGS would cull it: z <= 0.2, a singular 2D
/// covariance, or a 3σ rectangle that touches no tile.
bool project_gaussian(const Vec3f& mean, const Vec3f& scale, const Vec4f& rotation, const Camera& cam,
                      ProjectedGaussian* out);

/// Per-pixel contribution lists in CSR form: pixel p's contributors are
/// ids[offsets[p] .. offsets[p+1]) front to back, with their blending weights α·T.
struct ContributorLists {
  std::vector<uint64_t> offsets;
  std::vector<uint32_t> ids;
  std::vector<float> weights;
};

struct RenderOptions {
  bool rgb = true;            ///< colour from SH (view-dependent, degree as loaded)
  bool depth = false;         ///< Σ α·T·z (divide by alpha for the expected depth)
  const float* features = nullptr;  ///< optional [N][feature_channels] blended like colour
  int feature_channels = 0;
  bool contributors = false;  ///< per-pixel contributor lists (memory grows with depth complexity)
  bool max_weights = false;   ///< per-Gaussian maximum α·T over all pixels
  Vec3f background = Vec3f::Zero();
  Kernel kernel = Kernel::Default;
};

struct RenderOutput {
  int width = 0, height = 0;
  std::vector<float> rgb;       ///< [H][W][3], background included
  std::vector<float> depth;     ///< [H][W], Σ α·T·z
  std::vector<float> alpha;     ///< [H][W], 1 − final T (always filled)
  std::vector<float> features;  ///< [H][W][F]
  ContributorLists contributors;
  std::vector<float> max_weight;  ///< [N] when requested
  std::vector<int> radii;         ///< [N], 0 where culled
  size_t rendered = 0;            ///< Gaussians with radius > 0
  size_t tile_entries = 0;        ///< Gaussian-tile pairs sorted
  uint64_t box_pixels = 0;        ///< Gaussian-pixel pairs in the α boxes the blend visited (the work)
};

/// Renders Gaussians (as evaluated at one time) into a camera.
RenderOutput render(const FrameGaussians& gaussians, const Camera& camera, const RenderOptions& options = {});

}  // namespace fillgs
