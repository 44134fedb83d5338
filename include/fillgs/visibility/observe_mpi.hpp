#pragma once
// Observation tables over MPI ranks (built when OpenMPI is found; FILLGS_WITH_MPI). Every
// rank reads the scene and the cameras and takes the camera poses p with p mod n = rank, so
// each pose's static answer is traced once in the job; all ranks walk the frames in order,
// and per frame their partial count rows are added on rank 0 (MPI_Reduce), which writes the
// tables (observe_io.hpp's write_observation). A rank holds one frame of the tables; the
// files are the single process's, byte for byte. Nothing here includes mpi.h.
#include "fillgs/visibility/observe_io.hpp"

namespace fillgs::mpi {

/// MPI for one command: initialised here unless it already is (then left running), finalised
/// by the destructor when this session initialised it.
class Session {
 public:
  Session();
  ~Session();
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;
  int rank() const { return rank_; }
  int size() const { return size_; }
  /// Collective: the lowest rank that passed ok = false, or -1 when every rank passed true.
  int first_failure(bool ok) const;
  /// Ends every rank at once (an error after the ranks started exchanging frames: the others
  /// would otherwise wait for it forever).
  [[noreturn]] void abort(int code) const;

 private:
  int rank_ = 0, size_ = 1;
  bool owns_ = false;
};

/// The frames of the whole job (options.frames and options.cameras must be empty), computed
/// over the ranks of MPI_COMM_WORLD. Collective: every rank calls the returned source; on
/// rank 0 the sink gets every frame in order and the summary adds up the ranks' views, rays
/// and probes (seconds: the slowest rank's); on the other ranks the sink is never called.
/// The arguments must outlive the source.
FrameSource observe_source(const GaussianCloud& cloud, const std::vector<Camera>& cameras, const std::vector<double>& times, double frame_step,
                           const ObservationOptions& options);

}  // namespace fillgs::mpi
