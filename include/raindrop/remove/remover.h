#pragma once
// The removal pipeline of docs/CONTRACTS.md section 2 between the three graphs:
//   R = input RGB in [0, 1]; E = edge map of the unpadded R; both padded (replicate, bottom
//   and right) to a multiple of the models' pad_multiple;
//   P = RDN(R); M0 = P > threshold; M = elliptical dilation of M0 (k x k);
//   Ihat = clamp(3RN(R, E), 0, 1); B = M * Ihat + (1 - M) * R; out = clamp(RFN(B), 0, 1),
//   cropped back. It matches tools/raindrop_tools/reference.py to within 1/255 at scale 1
//   without the coarse pass for large drops (large_drops.h), which the reference does not have.
//
// Large images are tiled (see tiling.h) in two passes: pass 1 runs the RDN per tile and
// thresholds each pixel's probability from the one tile that owns it into a mask of the
// whole (padded) image; the dilation then runs once on that whole mask; pass 2 runs 3RN and
// RFN per tile with that mask and blends the tiles' outputs. Thresholding and dilating
// globally (rather than per tile) makes the mask exactly the whole-image mask: a binary
// decision has no sensible cross-fade, a per-tile dilation would need its own margins, and
// the mask costs 1 byte per pixel, less than the image itself. Memory beyond the input and
// output images: the mask (2 bytes per pixel), one tile's tensors and a float strip one
// tile high and the image wide.
//
// With two or more CPU threads a single-tile image runs its RDN and 3RN side by side on half
// the threads each, then RFN on all of them (Models::branches); StageTimes then sum the busy
// time of both sides, more than the wall time. Tiled images run in order.
#include <filesystem>
#include <exception>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>

#include <opencv2/core.hpp>

#include "raindrop/remove/detector_router.h"
#include "raindrop/remove/fine_drops.h"
#include "raindrop/remove/large_drops.h"
#include "raindrop/remove/model.h"
#include "raindrop/remove/session.h"
#include "raindrop/remove/stage_times.h"
#include "raindrop/remove/surround_fill.h"
#include "raindrop/remove/tiling.h"
#include "raindrop/remove/wet_gate.h"
#include "raindrop/remove/working_scale.h"

namespace raindrop::removal {

struct RemoveOptions {
  std::optional<double> threshold;  // default: the models' raindrop.threshold
  std::optional<int> dilation;      // default: the models' raindrop.dilation
  int tile = kDefaultTile;          // 0: whole image at once
  int overlap = kDefaultOverlap;
  bool keep_float = false;          // also return the float RGB output (before quantisation)
  // The scale the networks see the image at, in (0, 1]; default: auto_working_scale
  // (working_scale.h: the long side brought to the models' working size, never enlarged).
  std::optional<double> scale;
  // After the pass at that scale, a coarse pass at a third of it for drops too large for the
  // networks there (large_drops.h). Off: the working-scale pass alone.
  bool large_drops = true;
  // In that coarse pass, each drop's mask dilation grows with the drop (large_drops.h); 0: the
  // models' k for every drop.
  std::optional<double> large_drop_growth;  // default: the models' raindrop.large_drop_growth
  // The coarse pass replaces a large region only where the working-scale image is at most this
  // sharp (large_drops.h); infinity: every large region, as before the rule.
  double large_drop_max_sharpness = kLargeDropMaxSharpness;
  // Where the coarse pass's fill replaces the image, this times the input's fine detail is added
  // back (large_drops.h: add_input_detail); 0: the fill alone.
  double large_drop_detail = kLargeDropDetail;
  // Runs the 3RN and RFN on the image and on its mirror image and averages the two
  // (large_drops.h: run_mirror_averaged): twice their time for a better guess at what drops
  // hide. The coarse pass always does (kLargeDropMirrorAverage); this turns it on for the
  // working-scale pass too (raindrop-remove --mirror-average).
  bool mirror_average = false;
  // In the working-scale pass, parts of the mask at most this many pixels (given with the long
  // side at 512; run_native scales it to the pass's scale, surround_fill_area_at_scale) whose
  // surround is at most surround_fill_mad levels rough (median absolute deviation of its luma)
  // are filled from that surround instead of by the 3RN (surround_fill.h); 0: the 3RN
  // everywhere. Default: the area of the detector that decides the mask (ModelInfo::
  // surround_fill_area: 150 for the default's, 1500 for compact-windshield's, which a router
  // may choose per image; docs/RESULTS.md 4.44).
  std::optional<int> surround_fill_area;
  double surround_fill_mad = kSurroundFillMad;
  // Each part the surround fills first grows into its rim by up to this many pixels (given at
  // the scale that brings the long side to 512, scaled like surround_fill_area:
  // surround_fill_rim_at_scale): the dark rims and bright halos just past a real drop's mask
  // (surround_fill.h); 0: the parts as the detector found them.
  int surround_fill_rim = kSurroundFillRim;
  // Where the models have a detector router (detector_router.h) and the networks see the image
  // at the automatic working scale (no `scale`, or the one auto_working_scale gives: the scale
  // the router was fitted at), it chooses which detector decides the mask, for both passes.
  // Off: the models' own detector always. --threshold and --dilation apply to either detector.
  bool route = true;
  // After both passes, the deciding detector at 1.5 times the working scale, and the small
  // parts it finds over smooth surroundings filled from them (fine_drops.h). Off: no such pass.
  bool fine_drops = false;
  // Images the networks see at full size (the automatic scale at or below the working size, or
  // `scale` 1): the working-scale pass keeps the input's own pixels wherever its mask is 0, as
  // it always does for larger images (the composite of working_scale.h with the mask itself;
  // the coarse pass's soft rims still change pixels just outside the written mask, at every
  // size). Off (the default, the contract's step 7): the RFN's output everywhere; it refines
  // the whole blended image, and changed thousands of pixels of drop-free 512x256 street frames,
  // tens to hundreds of pixels from any detection, by up to about 30 levels. On: +0.3 dB on
  // held-out sparse rendered drops at 512x256, but the int8 default's gap between 512x288 and
  // 1280x720 frames (issue target: 1 dB) then measures 1.002 dB (docs/RESULTS.md 4.70).
  bool keep_outside_mask = false;
  // A camera's wet gate (wet_gate.h), checked against the models by the caller
  // (check_wet_gate): where it judges the image dry from the working pass's detector maps, the
  // result is the input as it was and an empty mask. It judges at the automatic working scale,
  // where it was fitted: with a `scale` other than that, run() refuses. None: every image is
  // processed.
  std::shared_ptr<const WetGate> wet_gate;
};

struct RemoveResult {
  cv::Mat image;  // the input's size, channel count and depth (alpha copied through)
  cv::Mat mask;   // CV_8UC1, 0 or 255: the final mask M (after threshold and dilation)
  cv::Mat rgb;    // CV_32FC3 in [0, 1], keep_float only: clamp(RFN(B)) cropped, RGB
  StageTimes times;
  int tiles_x = 1, tiles_y = 1;
  // Pixels the detectors ran on (sum of the tiles' padded areas; twice where the router sent
  // the image to its alternative detector, which runs after the first).
  double network_pixels = 0;
  // Pixels the 3RN and RFN ran on: each pass's padded canvas, less a coarse pass that found no
  // large drop (it stops after its detector); a mirror-averaged pass counts twice (it runs them twice).
  double reconstructed_pixels = 0;
  double scale = 1.0;         // the scale the networks saw the image at
  double coarse_scale = 0;    // the coarse pass's scale (large_drops.h); 0 when it did not run
  int large_drops = 0;        // drops the coarse pass found large and replaced
  int surround_filled = 0;    // parts of the mask filled from their surround (surround_fill.h)
  int sharp_large_drops = 0;  // regions it found large but left alone: too sharp (large_drops.h)
  double fine_scale = 0;      // the fine pass's scale (fine_drops.h); 0 when it did not run
  int fine_drops = 0;         // small drops it filled
  // The router's z for this image (detector_router.h); empty when it did not run.
  std::optional<double> router_score;
  // Whether the router's alternative detector decided the mask (z > 0).
  bool alternative_detector() const { return router_score && *router_score > 0; }
  // The wet gate's z for this image (wet_gate.h); empty without a gate.
  std::optional<double> wet_gate_score;
  // Judged dry by the wet gate (z <= 0): image is the input, the mask empty.
  bool judged_dry() const { return wet_gate_score && *wet_gate_score <= 0; }
};

class Remover {
 public:
  // Loads and checks rdn.onnx, rrn.onnx and rfn.onnx of `model_dir` (raindrop::Error if
  // anything is missing or off-contract). The coarse pass's large drops are reconstructed by
  // the 3RN and RFN of `large_drop_dir` when given, else of the folder that `model_dir`'s
  // LARGE_DROPS file names (model_paths.h), else of `model_dir` itself. Those models (their
  // rrn.onnx and rfn.onnx only) are loaded on the first large drop (a photograph without one
  // never pays for them); here their folder is only checked for the two files.
  //
  // With `use_router`, a ROUTER file in `model_dir` is read (a damaged one, or one naming a
  // folder without rdn.onnx, is a raindrop::Error here) and its alternative detector is
  // loaded on the first image the router sends to it; without, the file is not read at all.
  explicit Remover(const std::filesystem::path& model_dir, const SessionConfig& config = {},
                   const std::optional<std::filesystem::path>& large_drop_dir = std::nullopt,
                   bool use_router = true);

  // image: CV_8U, CV_16U or CV_32F with 1-4 channels (see pixels.h), any size >= 1x1.
  // At a scale below 1 the networks run on a downscaled copy and the correction comes back
  // as working_scale.h says: pixels outside the mask are the input's own. Then, unless
  // options.large_drops is off, a coarse pass replaces drops too large for that scale.
  RemoveResult run(const cv::Mat& image, const RemoveOptions& options = {});

  const ModelInfo& info() const { return models_.info(); }
  const std::filesystem::path& model_dir() const { return models_.dir(); }
  // The folder whose 3RN and RFN reconstruct large drops; empty when it is model_dir().
  const std::filesystem::path& large_drop_model_dir() const { return large_drop_dir_; }
  // The router read from the models' ROUTER file, and its alternative's folder (empty without).
  const std::optional<DetectorRouter>& router() const { return router_; }
  const std::filesystem::path& alternative_detector_dir() const { return alternative_dir_; }

 private:
  // Decides after detection whether reconstruction is worth running, from the dilated mask
  // (CV_8U 0/1, the image's size).
  using MaskGate = std::function<bool(const cv::Mat& mask)>;
  // Which detector decides a pass's mask: `models` (nullptr: the main models), or, with `route`,
  // the models it returns when given the main detector's probability map (CV_32F, the image's
  // size): the main models (their map is thresholded as it is) or others (their detector runs
  // on the same inputs). Threshold, dilation and growth are the deciding detector's.
  struct Detection {
    Models* models = nullptr;
    std::function<Models*(const cv::Mat& prob)> route;
    // Shown the first detector's maps (CV_32F, the image's size) before `route`: its own and,
    // with `observe_alternative`, the second map its graph computes (kAlternativeOutput). When it
    // returns true the pass stops there (a dry image, wet_gate.h): an empty mask, no image or rgb.
    std::function<bool(const cv::Mat& prob, const cv::Mat& alternative_prob)> observe;
    bool observe_alternative = false;
    // The whole image's size and the scale the pass runs at, for surround_fill_area_at_scale
    // (scale 0: the area as given).
    cv::Size image_size;
    double scale = 0;
    // A single tile's detector on all the threads (a pass that runs nothing beside it: the fine
    // pass) instead of the half it gets beside the 3RN.
    bool all_threads = false;
  };
  // The pipeline at the image's own size (the networks see every pixel). With a `gate` that
  // returns false, it stops after detection: the result then holds the mask and the times
  // only (image empty), and the 3RN does not run beside the RDN (it might be wasted): a single
  // tile then runs both, one after the other, on the half-thread sessions.
  // `reconstruction` names the models whose 3RN and RFN run after the detector (default: the
  // main ones); `detection` which detector decides the mask, and its `route` (after the first
  // detector's run: the working pass's router, or the coarse pass waiting for its choice) which
  // one replaces it. `grow_large_drops`: the mask's dilation grows with each drop by the deciding
  // detector's large-drop growth or the option's (mask.h: dilate_mask_by_size), the coarse
  // pass's only.
  RemoveResult run_native(const cv::Mat& image, const RemoveOptions& options, const MaskGate& gate,
                          const std::function<Models&()>& reconstruction, bool grow_large_drops,
                          const Detection& detection);
  // The models for the coarse pass's large drops (made on first use), or models_.
  Models& large_drop_models();
  // The router's alternative detector (made on first use).
  Models& alternative_detector();
  // Threads for the full-size composite: the session threads (0: one per core), on the CPU.
  int composite_workers() const;
  // The pipeline on `small` (the image area-averaged down to the working scale), brought back
  // to the image's size.
  RemoveResult run_scaled(const cv::Mat& image, const cv::Mat& small, const RemoveOptions& options, double scale,
                          const Detection& detection);
  // The coarse pass for large drops (large_drops.h) at a third of `scale`, on its own: it reads
  // only the image and `working` (the image as the working-scale pass sees it), so it can run
  // beside that pass. Its result goes over the working-scale result in composite_large_drops.
  // `route`: the working pass's router's choice of detector, which it may have to wait for;
  // nullptr: the main models' detector.
  class RouteDecision;
  // The wet gate's verdict (true: dry), which a coarse pass waits for before it reconstructs;
  // nullptr: no gate.
  class WetVerdict;
  struct CoarsePass {
    double coarse_scale = 0;  // 0: the coarse copy was too small to run (coarse_pass_fits)
    RemoveResult result;      // rgb: the coarse copy's reconstruction (when large drops were found)
    cv::Mat large;            // the large drops' mask at the coarse scale (CV_8U 0/255)
    int large_drops = 0, sharp_large_drops = 0;
    double convert_ms = 0;
  };
  CoarsePass coarse_pass(const cv::Mat& image, const cv::Mat& working, const RemoveOptions& options, double scale,
                         const RouteDecision* route, const WetVerdict* verdict);
  void composite_large_drops(const cv::Mat& image, const CoarsePass& coarse, const RemoveOptions& options, double scale,
                             RemoveResult& res);
  // The fine pass (fine_drops.h) over `res`, the result of both passes at `scale`.
  void fine_pass(const cv::Mat& image, const RemoveOptions& options, double scale, RemoveResult& res);

  // Companion models loaded on first use, once; a failed load is kept and rethrown for every
  // later image (a folder run with --keep-going then reports it per image without loading the
  // graphs again).
  class LazyModels {
   public:
    LazyModels(Models::Graphs graphs, std::string role, std::string hint)
        : graphs_(graphs), role_(std::move(role)), hint_(std::move(hint)) {}
    // The models of `dir`, loaded with `config`; they must accept `main`'s padded canvas.
    Models& get(const std::filesystem::path& dir, const SessionConfig& config, const Models& main);
    // Before the first get(): which graphs it loads.
    void set_graphs(Models::Graphs graphs) { graphs_ = graphs; }

   private:
    Models::Graphs graphs_;
    std::string role_;  // what they are, for the error message
    std::string hint_;  // the options that do without them, for the error message
    std::unique_ptr<Models> models_;
    std::mutex mutex_;
    std::exception_ptr failure_;
  };

  Models models_;
  SessionConfig config_;
  std::filesystem::path large_drop_dir_;  // empty: the main models reconstruct large drops too
  LazyModels large_models_{Models::Graphs::reconstruction, "the large drops' models",
                           "choose others with --large-drop-models DIR, or run without the coarse pass: --no-large-drops"};
  std::optional<DetectorRouter> router_;
  std::filesystem::path alternative_dir_;
  // The main detector's graph has the alternative's map as its second output (model.h).
  bool alternative_in_main_graph_ = false;
  LazyModels alternative_{Models::Graphs::detection, "the router's detector models", "run without the router: --no-router"};
};

namespace detail {

// A result computed on a small copy, brought back over `base` at full size (working_scale.h):
// out = (1 - a) base + a up(rgb_small), a = up(weight_small) bilinear, where the base is the
// input or a finer pass's output (`base_rgb`: its float RGB, or empty to convert `base`).
// Where a == 0 the base's own pixels, bit for bit (no round trip through float). `mask`
// (CV_8U 0/255) marks a >= 0.5; `rgb` (keep_float) holds the blended float rows. The weights
// must be finite, in [0, 1] (both callers make them from 8-bit masks). Work is split among
// `workers` threads. In the header for its tests (Remover::run is how it is used).
struct Upsampled {
  cv::Mat image, mask, rgb;
};
Upsampled composite_upsampled(const cv::Mat& base, const cv::Mat& base_rgb, const cv::Mat& rgb_small,
                              const cv::Mat& weight_small, bool keep_float, int workers);

}  // namespace detail

}  // namespace raindrop::removal
