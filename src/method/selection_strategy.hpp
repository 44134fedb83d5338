#pragma once
// The selection strategies behind one interface (select.hpp, SelectOptions::strategy). Each
// is a small class in its row's file under src/method/strategies/ (method/strategies.hpp)
// that owns its own state and decides everything it does differently (its starts, paths,
// scores, and its order of a pool: pool_order). Adding a strategy is adding that file.
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "fillgs/model/frame_grid.hpp"
#include "fillgs/method/select.hpp"
#include "fillgs/visibility/visibility.hpp"

namespace fillgs {

/// What every strategy may read and share: the selection's inputs and options, the
/// deficiency field (C and D, updated with every accepted view), the scene's visibility
/// engine and frame sampler, and the world axis closest to the cameras' up.
struct SelectionContext {
  const SelectInput& in;
  const SelectOptions& options;
  DeficiencyField& field;
  VisibilityEngine& engine;
  FrameSampler& sampler;
  int vertical;
  double time_of(int f) const { return FrameGrid(in.frames).time(f); }
};

class SelectionStrategy {
 public:
  /// Where trajectories start: the observed views by the exploration priority E (highest
  /// first, or lowest first), or in a random order.
  enum class Starts { HighestPriority, LowestPriority, Shuffled };
  /// How a trajectory is made: grown from its start by scored candidates (the paper, Sec. 3.3), a random
  /// walk from a random free position, or poses between neighbouring training cameras.
  enum class Paths { Grown, RandomWalk, BetweenCameras };

  virtual ~SelectionStrategy() = default;
  virtual Starts starts() const { return Starts::Shuffled; }
  virtual Paths paths() const { return Paths::Grown; }
  /// Whether the lowest score wins (negative); otherwise the highest.
  virtual bool lowest_wins() const { return false; }
  /// One score per candidate, all at `frame`.
  virtual std::vector<double> score(const std::vector<Camera>& candidates, int frame) {
    (void)frame;
    return std::vector<double>(candidates.size(), 0.0);
  }
  /// A virtual view accepted at `frame` (the field has already counted it).
  virtual void accept(const Camera& view, int frame) { (void)view, (void)frame; }
  /// Choosing among a pool of real camera-times (select_from_pool): a strategy that does not
  /// score them returns its own order here, each with the score it records, `shuffled` being
  /// the pool in the selection seed's random order; nullopt (the default): the pool is
  /// scored frame by frame and chosen greedily.
  virtual std::optional<std::vector<std::pair<size_t, double>>> pool_order(const std::vector<ObservedView>& pool,
                                                                           const std::vector<Camera>& training,
                                                                           const std::vector<size_t>& shuffled) const {
    (void)pool, (void)training, (void)shuffled;
    return std::nullopt;
  }
};


}  // namespace fillgs
