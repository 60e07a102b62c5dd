#pragma once
// One run split over N processes or machines: `--shard K/N` (raindrop-render, and
// raindrop-remove's folder mode). K is 0-based, 0 <= K < N, as Slurm's SLURM_ARRAY_TASK_ID
// (with --array=0-<N-1>) and Kubernetes' JOB_COMPLETION_INDEX count.
//
// Shard K takes the inputs whose name hashes to K: hash_string(name) mod N, with the name
// raindrop-render's input id (the id in the manifest without "_v<variant>": all variants of
// an input go to one shard, which decodes it once) or, for raindrop-remove, the input's path
// relative to the input folder. A stable hash of the name rather than round-robin over the
// sorted list: an input's shard depends on its own name only, so adding or removing inputs,
// --limit or a list's order never moves an existing input to another shard, and a shard's
// resume still finds its finished samples. The price: shard sizes vary by about sqrt(n/N)
// inputs (even for large runs, uneven for a handful of inputs).
#include <string>
#include <string_view>

namespace raindrop {

struct Shard {
  int index = 0;  // K
  int count = 1;  // N; 1: the whole run (no shard)

  bool sharded() const { return count > 1; }
  bool owns(std::string_view name) const;
  std::string text() const;  // "K/N"
};

// "K/N" with 0 <= K < N; throws raindrop::Error (one line) otherwise.
Shard parse_shard(const std::string& text);

}  // namespace raindrop
