#pragma once
// Gaussians in PLY files, what the readers of src/io/formats/ share: the standard 3DGS
// vertex properties (x y z, scale_*, rot_*, opacity, f_dc_*, f_rest_*), read once here for
// every format that stores them (3DGS, the fillgs 4D PLY, Spacetime Gaussians, Ex4DGS, the
// canonical clouds of deformation models, per-frame PLYs).
#include <string>
#include <vector>

#include "fillgs/io/ply.hpp"
#include "fillgs/model/gaussians.hpp"

namespace fillgs::model_io {

/// The fillgs 4D PLY's header comment (data/README.md).
constexpr const char* kFillgsMagic = "fillgs_4d 1";

/// The SH degree (0..3) that `rest_prefix`* properties make; one line otherwise.
int sh_degree_of(const PlyElement& v, const std::string& rest_prefix);

/// SH coefficients (`dc_prefix`0..2, `rest_prefix`*, channel-major as 3DGS writes them) of
/// rows r into Gaussians target_ids[r] of `c` (whose sh_degree must match).
void read_sh(const PlyElement& v, const std::string& dc_prefix, const std::string& rest_prefix, GaussianCloud& c,
             const std::vector<uint32_t>& target_ids);

/// Position (without a prefix only), scale, rotation (without a prefix only) and opacity
/// of rows r into Gaussians ids[r]. An opacity logit of +-inf (opacity exactly 1 or 0, as
/// some exporters write it) is kept as +-40, with a note; NaN is an error.
/// With `saturated`, the count of such logits is added there instead (a reader of blocks
/// notes them once, note_saturated).
void read_base(const PlyElement& v, GaussianCloud& c, const std::vector<uint32_t>& ids, const std::string& prefix = "",
               size_t* saturated = nullptr);

/// The note read_base makes of `saturated` infinite opacity logits in `source` (none for 0).
void note_saturated(GaussianCloud& c, size_t saturated, const std::string& source);

/// first, first + 1, ..., first + n - 1.
std::vector<uint32_t> iota_ids(size_t n, uint32_t first = 0);

/// Throws one line if `ply` (whose header is `header`) is the canonical PLY of a deformation
/// model (embedding_* properties, or deformation.pth / deform/ beside it), which is no frame
/// of the video, saying what to pass instead. Every reader of a plain PLY asks this first.
void refuse_canonical_ply(const std::string& ply, const std::string& header);

/// A static cloud from a vertex element with the standard 3DGS properties.
GaussianCloud read_standard_vertex(const PlyElement& v);

/// read_standard_vertex a block of rows at a time: a sink for read_ply that builds `c` from
/// the vertex element's rows as they are read (their columns are never kept), counting
/// infinite opacity logits into `saturated` (note_saturated after the read).
PlyElementSink standard_vertex_sink(GaussianCloud& c, size_t& saturated);

/// The same Gaussians as a ModelState (a deformation model's canonical cloud, a frame of a
/// sequence); the reader's notes are appended to `notes`.
ModelState read_vertex_state(const PlyElement& v, std::vector<std::string>& notes);

}  // namespace fillgs::model_io
