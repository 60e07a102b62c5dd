#pragma once
// Rendering a data set: every input x every variant, in parallel, resumable.
//
// A sample is finished when its three images are in place (each written atomically) and its
// manifest line is appended. A rerun with the same settings skips finished samples; a rerun
// into a folder rendered with other settings is refused rather than mixing the two.
// Results are byte-identical for a given input, seed and settings whatever the thread count:
// each sample draws from its own random stream and every pixel is computed independently.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "raindrop/common/image_io.h"
#include "raindrop/common/shard.h"
#include "raindrop/render/framing.h"
#include "raindrop/render/inputs.h"
#include "raindrop/render/renderer.h"
#include "raindrop/render/scene_config.h"

namespace raindrop {

struct RenderOptions {
  std::filesystem::path out_dir = "out/render";
  int variants = 1;
  std::uint64_t seed = 0;
  int threads = 0;  // 0: all cores
  SceneConfig scene;
  std::optional<cv::Size> size;  // empty: keep each input's size
  bool convert = false;          // accept 16-bit / grey / RGBA inputs by converting them
  bool keep_going = false;       // render the rest after a failing input
  bool progress = true;
  int png_level = kDefaultPngLevel;  // PNG compression (image_io.h: kPngRunLength or a zlib level 0-9)
  int contact_sheet_rows = 0;    // > 0: keep this many samples for a contact sheet
  // Render only this shard's inputs (all their variants), into manifest.part-K-of-N.jsonl (shard.h); the
  // folder is shared with the other shards. A run without shard also takes over the
  // samples of any parts in the folder and merges them into its manifest.jsonl.
  Shard shard;
};

struct SampleView {  // a finished sample kept for a contact sheet
  std::string id;
  cv::Mat clean, rainy, mask;
};

struct RenderSummary {
  std::int64_t rendered = 0, skipped = 0, failed = 0;
  double coverage_sum = 0;  // over rendered samples
  std::int64_t drops_sum = 0;
  std::vector<std::string> errors;  // one line each
  std::vector<SampleView> samples;  // first contact_sheet_rows samples, by id
  double seconds = 0;
};

std::string renderer_version();

// The coverage image a sample with a lens writes as alpha/<name>.png: coverage in [0, 1] as
// 16-bit (the pinhole mask's 0/1 when the lens was skipped).
cv::Mat alpha16(const RenderedFrame& f);

// Whether `frame`, made from `rgb` (read_rgb8 with its `stored_png` bytes), is that input as it was
// (no crop or resize) in a file whose bytes can stand for it: then a clean image that is the frame
// itself (the street in focus) is written as those bytes, not encoded again.
bool frame_is_stored_input(const cv::Mat& rgb, const Frame& frame, const std::string& stored_png);

// Derives the seed of one sample from the run seed, the input id and the variant.
std::uint64_t sample_seed(std::uint64_t run_seed, const std::string& input_id, int variant);

// Throws raindrop::Error for problems that stop the whole run before anything is written
// (unwritable output, a folder rendered with other settings, a bad input header when not
// keep_going). Per-sample failures are reported in the summary.
RenderSummary render_dataset(const std::vector<InputImage>& inputs, const RenderOptions& options);

// Merges the manifest parts of the N shards of a run in `dir` (and a manifest.jsonl there)
// into manifest.jsonl, byte for byte what one run without --shard writes, and removes the
// parts. Refuses, touching nothing, a folder in use, a missing part (unless an earlier
// merge's manifest.jsonl is there), parts of different N or of different settings. Returns the number of samples in the manifest.
std::int64_t merge_shards(const std::filesystem::path& dir);

}  // namespace raindrop
