#include "raindrop/remove/remover.h"

#include <chrono>
#include <cstring>
#include <cmath>
#include <exception>
#include <functional>
#include <future>
#include <thread>
#include <numeric>
#include <string>
#include <vector>

#include "raindrop/common/error.h"
#include "raindrop/common/stopwatch.h"
#include "raindrop/remove/edge_map.h"
#include "raindrop/remove/large_drops.h"
#include "raindrop/remove/mask.h"
#include "raindrop/remove/model_paths.h"
#include "raindrop/remove/pixels.h"
#include "raindrop/remove/surround_fill.h"

#include <opencv2/imgproc.hpp>

namespace raindrop::removal {
namespace {

int round_up(int v, int a) { return (v + a - 1) / a * a; }

// One tile's network inputs: R (3 planes) and E (1 plane), NCHW with N = 1.
struct TileInputs {
  int h = 0, w = 0;
  std::vector<float> r, e;
};

// The window [y0, y1) x [x0, x1) of the padded canvas. The edge map is computed on the real
// pixels of the window plus a one-pixel ring (clipped at the image border), which is exactly
// the whole-image edge map there; padded rows/columns then repeat the last real one, for R
// and E alike (the reference pads E after computing it).
TileInputs build_inputs(const cv::Mat& image, int y0, int y1, int x0, int x1, StageTimes& t) {
  auto clock = Clock::now();
  const int H = image.rows, W = image.cols;
  const int ry0 = std::max(0, y0 - 1), ry1 = std::min(H, y1 + 1);
  const int rx0 = std::max(0, x0 - 1), rx1 = std::min(W, x1 + 1);
  const cv::Mat rgb = to_rgb_float(image, cv::Rect(rx0, ry0, rx1 - rx0, ry1 - ry0));
  t.convert += lap_ms(clock);
  const cv::Mat edge = edge_map(rgb);
  t.edge += lap_ms(clock);
  TileInputs in;
  in.h = y1 - y0;
  in.w = x1 - x0;
  const size_t plane = static_cast<size_t>(in.h) * in.w;
  in.r.resize(3 * plane);
  in.e.resize(plane);
  std::vector<int> cols(in.w);
  for (int x = x0; x < x1; ++x) cols[x - x0] = std::min(x, W - 1) - rx0;
  for (int y = y0; y < y1; ++y) {
    const int cy = std::min(y, H - 1) - ry0;
    const float* src = rgb.ptr<float>(cy);
    const float* esrc = edge.ptr<float>(cy);
    const size_t row = static_cast<size_t>(y - y0) * in.w;
    float* r = in.r.data() + row;
    float* g = r + plane;
    float* b = g + plane;
    float* e = in.e.data() + row;
    for (int x = 0; x < in.w; ++x) {
      const int cx = cols[x];
      r[x] = src[3 * cx];
      g[x] = src[3 * cx + 1];
      b[x] = src[3 * cx + 2];
      e[x] = esrc[cx];
    }
  }
  t.convert += lap_ms(clock);
  return in;
}

void clamp_all(std::vector<float>& v) {
  for (float& x : v) x = clamp01(x);
}

// Runs jobs[0..n) with jobs[1..] on their own threads and jobs[0] on the caller's; waits for
// all of them (they share the caller's buffers), then rethrows the first failure.
void run_side_by_side(const std::vector<std::function<void()>>& jobs) {
  std::vector<std::future<void>> others;
  for (size_t i = 1; i < jobs.size(); ++i) others.push_back(std::async(std::launch::async, jobs[i]));
  std::exception_ptr failure;
  try {
    if (!jobs.empty()) jobs[0]();
  } catch (...) {
    failure = std::current_exception();
  }
  for (auto& f : others) {
    try {
      f.get();
    } catch (...) {
      if (!failure) failure = std::current_exception();
    }
  }
  if (failure) std::rethrow_exception(failure);
}

// RDN on one tile's inputs, thresholded into `dst`: the part of the whole-image mask that the
// tile owns, at `owned` within the tile. `prob_dst` (when not empty) gets the probabilities there.
// `alternative_dst` (when not empty) gets the graph's second head's map there (model.h:
// kAlternativeOutput).
void detect(Network& rdn, const TileInputs& in, const cv::Rect& owned, double threshold, cv::Mat dst, StageTimes& t,
            cv::Mat prob_dst = {}, cv::Mat alternative_dst = {}) {
  auto clock = Clock::now();
  const size_t n = static_cast<size_t>(in.h) * in.w;
  std::vector<float> prob(alternative_dst.empty() ? n : 2 * n);
  rdn.run({in.r.data()}, in.h, in.w, prob.data(), alternative_dst.empty() ? nullptr : prob.data() + n);
  t.rdn += lap_ms(clock);
  const cv::Mat owned_prob = cv::Mat(in.h, in.w, CV_32F, prob.data())(owned);
  threshold_mask(owned_prob, threshold, dst);
  if (!prob_dst.empty()) owned_prob.copyTo(prob_dst);
  if (!alternative_dst.empty()) cv::Mat(in.h, in.w, CV_32F, prob.data() + n)(owned).copyTo(alternative_dst);
  t.mask += lap_ms(clock);
}

}  // namespace

namespace {

// What the working-scale pass decides and the coarse pass, running beside it, waits for (or for
// the failure that stopped it deciding); the first word counts.
template <class T>
class OnceDecided {
 public:
  void decide(T value) {
    std::call_once(once_, [&] { promise_.set_value(value); });
  }
  void fail(std::exception_ptr e) {
    std::call_once(once_, [&] { promise_.set_exception(e); });
  }
  T wait() const { return decided_.get(); }
  // Whether the value (or the failure) is there already: wait() would not block.
  bool ready() const { return decided_.wait_for(std::chrono::seconds(0)) == std::future_status::ready; }

 private:
  std::promise<T> promise_;
  std::shared_future<T> decided_ = promise_.get_future().share();
  std::once_flag once_;
};

}  // namespace

// The detector an image's passes share: the working-scale pass's router decides it.
class Remover::RouteDecision : public OnceDecided<Models*> {
 public:
  Models& wait() const { return *OnceDecided::wait(); }
};

// Whether the wet gate judged the image dry (wet_gate.h): then the coarse pass reconstructs nothing.
class Remover::WetVerdict : public OnceDecided<bool> {};

namespace {

// 3RN on one tile's inputs, clamped to [0, 1]; with `mirror`, averaged with its run on the
// mirror image (large_drops.h: kLargeDropMirrorAverage).
std::vector<float> reconstruct(Network& rrn, const TileInputs& in, StageTimes& t, bool mirror = false) {
  auto clock = Clock::now();
  std::vector<float> ihat(3 * static_cast<size_t>(in.h) * in.w);
  if (mirror) {
    run_mirror_averaged(rrn, {in.r.data(), in.e.data()}, {3, 1}, in.h, in.w, 3, ihat.data());
  } else {
    rrn.run({in.r.data(), in.e.data()}, in.h, in.w, ihat.data());
  }
  clamp_all(ihat);
  t.rrn += lap_ms(clock);
  return ihat;
}

}  // namespace

Remover::Remover(const std::filesystem::path& model_dir, const SessionConfig& config,
                 const std::optional<std::filesystem::path>& large_drop_dir, bool use_router)
    : models_(model_dir, config), config_(config) {
  if (use_router) {
    router_ = read_detector_router(model_dir);
    if (router_) {
      alternative_dir_ = sibling_model_folder(model_dir, router_->alternative);
      // The main detector's graph computes the alternative's map too (model.h): no second run.
      alternative_in_main_graph_ = models_.info().alternative_detector == router_->alternative;
      // Then its own graph never runs (every pass takes the map from the main graph): its
      // metadata (threshold, dilation, growth, fill area) is all that is read of it.
      if (alternative_in_main_graph_) alternative_.set_graphs(Models::Graphs::metadata);
      try {
        check_model_files(alternative_dir_, /*detector=*/true, /*reconstruction=*/false);
      } catch (const Error& e) {
        throw Error("'" + (model_dir / "ROUTER").string() + "' names the detector of '" + router_->alternative +
                    "', but: " + e.what() + " (run without the router: --no-router)");
      }
    }
  }
  try {
    const std::optional<std::filesystem::path> dir = large_drop_dir ? large_drop_dir : large_drop_companion(model_dir);
    if (dir && !same_folder(*dir, model_dir)) {
      check_model_files(*dir, /*detector=*/false);
      large_drop_dir_ = *dir;
    }
  } catch (const Error& e) {
    if (large_drop_dir) throw;  // the caller's folder: the error names it already
    throw Error("'" + (model_dir / "LARGE_DROPS").string() + "' names the models for large drops, but: " + e.what() +
                " (choose others with --large-drop-models DIR, or run without the coarse pass: --no-large-drops)");
  }
}

int Remover::composite_workers() const {
  if (config_.device != Device::cpu) return 1;
  return config_.threads > 0 ? config_.threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
}

Models& Remover::LazyModels::get(const std::filesystem::path& dir, const SessionConfig& config, const Models& main) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (failure_) std::rethrow_exception(failure_);
  if (!models_) {
    try {
      std::unique_ptr<Models> loaded;
      try {
        loaded = std::make_unique<Models>(dir, config, graphs_);
      } catch (const Error& e) {
        throw Error(role_ + ": " + e.what() + " (" + hint_ + ")");  // which models, and the way round them
      }
      // They run on a canvas padded for the main models.
      if (main.info().pad_multiple % loaded->info().pad_multiple != 0)
        throw Error(role_ + " '" + dir.string() + "' take sizes padded to a multiple of " +
                    std::to_string(loaded->info().pad_multiple) + ", the main models pad to " +
                    std::to_string(main.info().pad_multiple));
      models_ = std::move(loaded);
    } catch (...) {
      failure_ = std::current_exception();
      throw;
    }
  }
  return *models_;
}

Models& Remover::large_drop_models() {
  if (large_drop_dir_.empty()) return models_;
  return large_models_.get(large_drop_dir_, config_, models_);
}

// Loaded on the first image sent to it: most runs of the default on synthetic frames never need it.
Models& Remover::alternative_detector() { return alternative_.get(alternative_dir_, config_, models_); }

RemoveResult Remover::run(const cv::Mat& image, const RemoveOptions& opt) {
  check_input_format(image);
  check_tile_options(opt.tile, opt.overlap);
  if (opt.scale && !(*opt.scale > 0.0 && *opt.scale <= 1.0))
    throw Error("--scale must be a number in (0, 1], got " + std::to_string(*opt.scale));
  if (opt.large_drop_growth && !(*opt.large_drop_growth >= 0 && *opt.large_drop_growth <= kMaxLargeDropGrowth))
    throw Error("--large-drop-growth must be between 0 and " + std::to_string(static_cast<int>(kMaxLargeDropGrowth)));
  if (std::isnan(opt.large_drop_max_sharpness) || opt.large_drop_max_sharpness < 0)
    throw Error("--large-drop-sharpness must be a number >= 0 (inf: no limit)");
  if (!(opt.large_drop_detail >= 0 && opt.large_drop_detail <= 1))
    throw Error("--large-drop-detail must be a number between 0 and 1");
  if (opt.surround_fill_area && *opt.surround_fill_area < 0)
    throw Error("--surround-fill-area must be a whole number >= 0 (0: off)");
  if (!(opt.surround_fill_mad >= 0)) throw Error("--surround-fill-mad must be a number >= 0");
  if (opt.surround_fill_rim < 0 || opt.surround_fill_rim > kMaxSurroundFillRim)
    throw Error("--surround-fill-rim must be between 0 and " + std::to_string(kMaxSurroundFillRim) + ", got " +
                std::to_string(opt.surround_fill_rim));
  const double auto_scale = auto_working_scale(image.size(), info().working_size);
  const double scale = opt.scale.value_or(auto_scale);
  const cv::Size small = scaled_size(image.size(), scale);
  // The image as the working-scale pass sees it; the coarse pass measures its sharpness there.
  cv::Mat working = image;
  double t_down = 0;
  if (small != image.size()) {
    auto clock = Clock::now();
    // Area averaging: every input pixel counts once (no aliasing of fine texture).
    cv::resize(image, working, small, 0, 0, cv::INTER_AREA);
    t_down = lap_ms(clock);
  }
  RemoveResult res;
  // The router decides from the working pass's main detector, at the scale it was fitted at.
  const bool route = router_ && opt.route && scale == auto_scale;
  RouteDecision decision;
  std::optional<double> router_score;
  Detection detection;
  detection.image_size = image.size();
  detection.scale = scale;
  // The wet gate judges from the working pass's maps; a dry image stops there, and the coarse
  // pass, before reconstructing large drops it found, waits for the verdict.
  std::optional<double> wet_score;
  WetVerdict verdict;
  if (opt.wet_gate) {
    if (scale != auto_scale)
      throw Error("--wet-gate judges an image at the automatic working scale it was fitted at: it cannot be used with --scale");
    detection.observe = [&](const cv::Mat& prob, const cv::Mat& alternative_prob) {
      wet_score = opt.wet_gate->score(prob, alternative_prob);
      const bool dry = *wet_score <= 0;
      verdict.decide(dry);
      // A dry image's pass ends before its router: a coarse pass waiting for the choice of
      // detector takes the main one (and then reconstructs nothing).
      if (dry) decision.decide(&models_);
      return dry;
    };
    detection.observe_alternative = opt.wet_gate->maps > 1;
  }
  if (route) {
    detection.route = [&](const cv::Mat& prob) {
      const double z = router_->score(router_features(prob));
      router_score = z;
      Models* chosen = z > 0 ? &alternative_detector() : &models_;
      decision.decide(chosen);
      return chosen;
    };
  }
  const auto working_pass = [&] {
    try {
      // At full size, keep_outside_mask composites the result over the input with the mask as
      // a larger image's is (an identity upsampling) instead of taking the RFN's output whole.
      res = small == image.size() && !opt.keep_outside_mask ? run_native(image, opt, {}, {}, false, detection)
                                                            : run_scaled(image, working, opt, scale, detection);
    } catch (...) {
      decision.fail(std::current_exception());  // a coarse pass waiting for the decision stops too
      verdict.fail(std::current_exception());   // or for the verdict
      throw;
    }
  };
  CoarsePass coarse;
  const auto large_drop_pass = [&] {
    coarse = coarse_pass(image, working, opt, scale, route ? &decision : nullptr, opt.wet_gate ? &verdict : nullptr);
  };
  if (opt.large_drops && models_.branches() > 1) {
    // Side by side: the coarse pass reads only the input, and its detector alone (what most
    // photographs need of it) left one core idle while it ran on the other (a fifth of a
    // 1280x720 photograph's time on two threads; docs/RESULTS.md 3.6).
    run_side_by_side({working_pass, large_drop_pass});
  } else {
    working_pass();
    if (opt.large_drops) large_drop_pass();
  }
  res.times.convert += t_down;
  res.router_score = router_score;
  res.wet_gate_score = wet_score;
  if (res.judged_dry()) {
    // Dry: the input as it was. The working pass stopped after its detector (a 3RN beside it
    // had run), the coarse pass after its own; their times are what the verdict cost.
    res.times += coarse.result.times;
    res.times.convert += coarse.convert_ms;
    res.network_pixels += coarse.result.network_pixels;
    res.image = image.clone();
    res.mask = cv::Mat::zeros(image.size(), CV_8U);
    res.rgb = opt.keep_float ? to_rgb_float(image, cv::Rect(0, 0, image.cols, image.rows)) : cv::Mat();
    return res;
  }
  if (opt.large_drops) composite_large_drops(image, coarse, opt, scale, res);
  if (opt.fine_drops) fine_pass(image, opt, scale, res);
  return res;
}

void Remover::fine_pass(const cv::Mat& image, const RemoveOptions& opt, double scale, RemoveResult& res) {
  const double fine = fine_drop_scale(scale);
  const cv::Size size = scaled_size(image.size(), fine);
  // Nothing finer to see: the networks saw every pixel already, or the sizes round alike.
  if (fine == 0 || size == scaled_size(image.size(), scale)) return;
  res.fine_scale = fine;
  auto clock = Clock::now();
  cv::Mat input_fine, output_fine;
  cv::resize(image, input_fine, size, 0, 0, cv::INTER_AREA);
  cv::resize(res.image, output_fine, size, 0, 0, cv::INTER_AREA);
  res.times.convert += lap_ms(clock);
  // The detector that decided the working pass's mask (the router's choice), with its own
  // threshold and dilation (or the options'); it stops at its mask: no 3RN at this scale, so
  // of the options only those of detection (threshold, dilation, tiles) count.
  Detection detection;
  detection.models = res.alternative_detector() && !alternative_in_main_graph_ ? &alternative_detector() : &models_;
  // The alternative's map from the main graph's second output (model.h), as the passes before.
  if (res.alternative_detector() && alternative_in_main_graph_)
    detection.route = [this](const cv::Mat&) { return &alternative_detector(); };
  detection.all_threads = true;
  const RemoveResult found = run_native(input_fine, opt, [](const cv::Mat&) { return false; }, {}, false, detection);
  res.times += found.times;
  res.network_pixels += found.network_pixels;
  clock = Clock::now();
  // Filled from the result (the drops the passes removed are gone from the surroundings).
  const int area = surround_fill_area_at_scale(kFineDropArea, image.size(), fine);
  cv::Mat weight;
  const cv::Mat filled = fill_fine_drops(to_rgb_float(output_fine, cv::Rect(0, 0, size.width, size.height)), found.mask,
                                         area, opt.surround_fill_mad, &weight, &res.fine_drops);
  if (res.fine_drops > 0) {
    detail::Upsampled up = detail::composite_upsampled(res.image, opt.keep_float ? res.rgb : cv::Mat(), filled, weight,
                                                       opt.keep_float, composite_workers());
    res.image = up.image;
    res.mask = res.mask | up.mask;
    if (opt.keep_float) res.rgb = up.rgb;
  }
  res.times.output += lap_ms(clock);
}

namespace detail {

Upsampled composite_upsampled(const cv::Mat& base, const cv::Mat& base_rgb, const cv::Mat& rgb_small,
                              const cv::Mat& weight_small, bool keep_float, int workers) {
  const cv::Size full = base.size();
  Upsampled up;
  up.image.create(full, base.type());
  up.mask.create(full, CV_8U);
  if (keep_float) up.rgb.create(full, CV_32FC3);
  const size_t pixel_bytes = base.elemSize();
  // One span of a band through float: the blend where a > 0, the base's own bytes elsewhere.
  const auto blend_span = [&](const cv::Rect& span) {
    cv::Mat span_alpha;
    const cv::Mat blended = blend_upsampled(base_rgb.empty() ? to_rgb_float(base, span) : base_rgb(span), span, full,
                                            rgb_small, weight_small, span_alpha);
    store_rgb_float(blended, up.image, span.tl());
    if (keep_float) blended.copyTo(up.rgb(span));
    // Where a == 0 the base's own pixels, bit for bit (no round trip through float).
    for (int y = 0; y < span.height; ++y) {
      const float* a = span_alpha.ptr<float>(y);
      const unsigned char* src = base.ptr<unsigned char>(span.y + y) + span.x * pixel_bytes;
      unsigned char* dst = up.image.ptr<unsigned char>(span.y + y) + span.x * pixel_bytes;
      for (int x = 0; x < span.width; ++x) {
        if (a[x] <= 0.0f) std::memcpy(dst + x * pixel_bytes, src + x * pixel_bytes, pixel_bytes);
      }
    }
  };
  // Bands of rows; in a band only the columns a drop's weight reaches are interpolated (it is
  // exactly 0 elsewhere: working_scale.h), and only the runs of columns where it is above 0 go
  // through float, split where at least kGap columns between drops need none. Most of a
  // photograph is the base's own bytes, copied (float work there was half of the full-size
  // cost: docs/RESULTS.md 3.6; scattered small drops made one span of nearly every band).
  constexpr int kBand = 16, kGap = 16;
  const auto composite_bands = [&](int first, int stride) {
    std::vector<unsigned char> drop_column;
    for (int y0 = first * kBand; y0 < full.height; y0 += stride * kBand) {
      const int rows = std::min(kBand, full.height - y0);
      const cv::Rect band(0, y0, full.width, rows);
      base(band).copyTo(up.image(band));
      up.mask(band).setTo(0);
      if (keep_float) (base_rgb.empty() ? to_rgb_float(base, band) : base_rgb(band)).copyTo(up.rgb(band));
      const cv::Rect reach = upsampled_reach(weight_small, full, band);
      if (reach.empty()) continue;
      const cv::Mat alpha = upsample_region(weight_small, full, reach);
      drop_column.assign(static_cast<size_t>(reach.width), 0);
      for (int y = 0; y < rows; ++y) {
        const float* a = alpha.ptr<float>(y);
        unsigned char* m = up.mask.ptr<unsigned char>(y0 + y) + reach.x;
        for (int x = 0; x < reach.width; ++x) {
          m[x] = a[x] >= 0.5f ? 255 : 0;
          drop_column[x] |= a[x] > 0.0f;
        }
      }
      for (int x = 0; x < reach.width;) {
        if (!drop_column[x]) {
          ++x;
          continue;
        }
        int end = x + 1, gap = 0;  // the run: up to its last drop column before a gap of kGap
        for (int i = end; i < reach.width && gap < kGap; ++i) {
          gap = drop_column[i] ? 0 : gap + 1;
          if (drop_column[i]) end = i + 1;
        }
        blend_span(cv::Rect(reach.x + x, y0, end - x, rows));
        x = end;
      }
    }
  };
  // Bands are independent (each writes its own rows): every n-th band to each of `workers`
  // threads, interleaved so that drops bunched in one part of the photograph (a windshield's
  // lower half) still share out evenly. The working pass's networks are done by now (the coarse
  // pass beside it may still run). An 11-megapixel photograph spent 0.16 s here on one thread.
  const int bands = (full.height + kBand - 1) / kBand;
  const int n = std::clamp(workers, 1, std::max(1, bands));
  std::vector<std::function<void()>> jobs;
  for (int i = 0; i < n; ++i) jobs.push_back([&, i] { composite_bands(i, n); });
  run_side_by_side(jobs);
  copy_alpha(base, up.image);
  return up;
}

}  // namespace detail

RemoveResult Remover::run_scaled(const cv::Mat& image, const cv::Mat& small, const RemoveOptions& opt, double scale,
                                 const Detection& detection) {
  RemoveOptions sub = opt;
  sub.scale = 1.0;
  sub.keep_float = true;
  RemoveResult res = run_native(small, sub, {}, {}, false, detection);
  res.scale = scale;
  if (res.rgb.empty()) return res;  // stopped after detection: judged dry (wet_gate.h)
  StageTimes& t = res.times;

  auto clock = Clock::now();
  cv::Mat mask_small;
  res.mask.convertTo(mask_small, CV_32F, 1.0 / 255.0);
  detail::Upsampled up = detail::composite_upsampled(image, cv::Mat(), res.rgb, mask_small, opt.keep_float, composite_workers());
  res.image = up.image;
  res.mask = up.mask;
  res.rgb = up.rgb;
  t.output += lap_ms(clock);
  return res;
}

Remover::CoarsePass Remover::coarse_pass(const cv::Mat& image, const cv::Mat& working, const RemoveOptions& opt,
                                         double scale, const RouteDecision* route, const WetVerdict* verdict) {
  CoarsePass cp;
  const double coarse_scale = scale / kLargeDropScaleDivisor;
  const cv::Size coarse = scaled_size(image.size(), coarse_scale);
  if (!coarse_pass_fits(coarse)) return cp;
  cp.coarse_scale = coarse_scale;
  auto clock = Clock::now();
  cv::Mat coarse_native;
  cv::resize(image, coarse_native, coarse, 0, 0, cv::INTER_AREA);
  cp.convert_ms = lap_ms(clock);
  RemoveOptions sub = opt;
  sub.scale = 1.0;
  sub.keep_float = true;
  sub.large_drops = false;
  sub.surround_fill_area = 0;  // the coarse pass's parts are large (surround_fill.h)
  sub.mirror_average = opt.mirror_average || kLargeDropMirrorAverage;
  // The coarse copy's detector is the main models' (it decides what is large, as it decides
  // what is a drop at the working scale), or the one the working pass's router chose; the large
  // drops' own models reconstruct them, loaded on the first large drop. docs/RESULTS.md 4.8: with
  // compact-real-coarse-long's 3RN and RFN, compact's detector did as well on real pairs as that
  // model's own (+4.63 against +4.65 dB on the train split), with one detector session instead
  // of two; other fine-tuned detectors took flat road for large drops.
  //
  // With a router, the main detector runs at once, beside the working pass, as without one; the
  // choice is waited for only after it (the working pass's detector, on 9 times the pixels, is
  // then nearly done), and where the router chose the other detector its map decides: from the
  // main graph's second output where it has one, else from a second run. A photograph the
  // router keeps so costs no more than without the router.
  Detection detection;
  // Decided already (one thread: the working pass ran first): no speculation, unless the choice's
  // map comes from the main graph, which then runs in any case.
  const bool speculative = route && (!route->ready() || alternative_in_main_graph_);
  detection.models = route && !speculative ? &route->wait() : &models_;
  if (speculative) detection.route = [route](const cv::Mat&) { return &route->wait(); };
  // Most photographs have no large drop: the coarse copy's detector decides before its 3RN
  // and RFN run, which are about two thirds of its cost.
  const MaskGate only_with_large_drops = [&](const cv::Mat& mask) {
    cp.large = large_drop_mask(mask, &cp.large_drops);
    // Only smooth regions: a sharp one is no defocused drop, and the coarse fill would blur it.
    if (cp.large_drops > 0 && std::isfinite(opt.large_drop_max_sharpness)) {
      const int found = cp.large_drops;
      cp.large = smooth_large_drops(cp.large, sharpness_map(working), opt.large_drop_max_sharpness, &cp.large_drops);
      cp.sharp_large_drops = found - cp.large_drops;
    }
    // A dry image's large drops are not reconstructed: the working pass's verdict is waited for
    // here, once there is something to reconstruct (its detector is then nearly done).
    if (cp.large_drops > 0 && verdict && verdict->wait()) cp.large_drops = cp.sharp_large_drops = 0;
    return cp.large_drops > 0;
  };
  cp.result = run_native(coarse_native, sub, only_with_large_drops, [this]() -> Models& { return large_drop_models(); },
                         /*grow_large_drops=*/true, detection);
  return cp;
}

void Remover::composite_large_drops(const cv::Mat& image, const CoarsePass& cp, const RemoveOptions& opt, double scale,
                                    RemoveResult& res) {
  if (cp.coarse_scale == 0) return;  // it did not run
  StageTimes& t = res.times;
  t.convert += cp.convert_ms;
  t += cp.result.times;
  res.network_pixels += cp.result.network_pixels;
  res.reconstructed_pixels += cp.result.reconstructed_pixels;
  res.coarse_scale = cp.coarse_scale;
  res.large_drops = cp.large_drops;
  res.sharp_large_drops = cp.sharp_large_drops;
  if (cp.large_drops == 0) return;
  auto clock = Clock::now();
  cv::Mat weight;
  cp.large.convertTo(weight, CV_32F, 1.0 / 255.0);
  // The reconstruction's 2-pixel checkerboard (large_drops.h) would come back as blocks several
  // pixels wide: smoothed away at the coarse copy's own scale first.
  cv::Mat smoothed;
  cv::GaussianBlur(cp.result.rgb, smoothed, cv::Size(0, 0), kLargeDropSmoothing, kLargeDropSmoothing,
                   cv::BORDER_REPLICATE);
  detail::Upsampled up = detail::composite_upsampled(res.image, opt.keep_float ? res.rgb : cv::Mat(), smoothed, weight, opt.keep_float,
                                     composite_workers());
  res.image = up.image;
  res.mask = res.mask | up.mask;
  if (opt.keep_float) res.rgb = up.rgb;
  // The input's fine detail back under the fill, sigma given at the working scale.
  add_input_detail(image, weight, kLargeDropDetailSigma / scale, opt.large_drop_detail, res.image,
                   opt.keep_float ? &res.rgb : nullptr);
  t.output += lap_ms(clock);
}

RemoveResult Remover::run_native(const cv::Mat& image, const RemoveOptions& opt, const MaskGate& gate,
                                 const std::function<Models&()>& reconstruction, bool grow_large_drops,
                                 const Detection& detection) {
  Models* detector = detection.models ? detection.models : &models_;
  double threshold = opt.threshold.value_or(detector->info().threshold);
  if (!std::isfinite(threshold)) throw Error("--threshold must be a finite number");
  // The models' own value was checked when they loaded (Models), so a bad k here is the option's.
  if (opt.dilation && (*opt.dilation < 1 || *opt.dilation > kMaxDilation))
    throw Error("--dilation must be between 1 and " + std::to_string(kMaxDilation) + ", got " +
                std::to_string(*opt.dilation));

  // A gated pass decides from the mask whether to reconstruct: the reconstruction's models
  // (made on first use) are asked for only then, on the detector's canvas.
  const int H = image.rows, W = image.cols, m = info().pad_multiple;
  const int Hp = round_up(H, m), Wp = round_up(W, m);
  const int align = std::lcm(2, m);
  const AxisLayout ly = layout_axis(Hp, opt.tile, opt.overlap, align);
  const AxisLayout lx = layout_axis(Wp, opt.tile, opt.overlap, align);
  const bool single = ly.count() == 1 && lx.count() == 1;

  RemoveResult res;
  res.tiles_y = ly.count();
  res.tiles_x = lx.count();
  StageTimes& t = res.times;

  // Pass 1: detection, thresholded into the whole-image mask from each pixel's owning tile.
  // A single tile's 3RN runs here too, beside its RDN, when there are threads for both
  // (Models::branches): it needs only the input.
  const int branches = single && !gate && !reconstruction ? models_.branches() : 1;
  cv::Mat mask0(Hp, Wp, CV_8U, cv::Scalar(0));
  cv::Mat prob;                   // the first detector's probabilities, for a router
  cv::Mat alternative_prob;       // and the alternative's, where the first's graph computes them
  // The alternative's map where a router may threshold it, or an observer reads it.
  const bool route_reads_alternative = detection.route && alternative_in_main_graph_;
  if (detection.route || detection.observe) {
    prob.create(Hp, Wp, CV_32F);
    if ((route_reads_alternative || (detection.observe && detection.observe_alternative)) && detector == &models_)
      alternative_prob.create(Hp, Wp, CV_32F);
  }
  TileInputs kept;                // the single tile's inputs, reused by pass 2
  std::vector<float> kept_ihat;   // and its 3RN output when it ran beside the RDN
  std::vector<StageTimes> worker_times(branches);
  double canvas_pixels = 0;
  for (int iy = 0; iy < ly.count(); ++iy)
    for (int ix = 0; ix < lx.count(); ++ix)
      canvas_pixels += static_cast<double>(ly.end[iy] - ly.begin[iy]) * (lx.end[ix] - lx.begin[ix]);
  // `models`' detector over the whole canvas, into mask0 (and prob, while it is kept).
  const auto detect_canvas = [&](Models& models, StageTimes& times) {
    res.network_pixels += canvas_pixels;
    if (single) {
      // rdn_beside() is the all-thread session when branches == 1.
      detect(detection.all_threads ? models.rdn() : models.rdn_beside(), kept, cv::Rect(0, 0, kept.w, kept.h), threshold,
             mask0, times, prob, alternative_prob);
      return;
    }
    for (int iy = 0; iy < ly.count(); ++iy) {
      for (int ix = 0; ix < lx.count(); ++ix) {
        const int y0 = ly.begin[iy], x0 = lx.begin[ix];
        const TileInputs in = build_inputs(image, y0, ly.end[iy], x0, lx.end[ix], times);
        const cv::Rect owned(lx.owned_begin(ix), ly.owned_begin(iy), lx.owned_end(ix) - lx.owned_begin(ix),
                             ly.owned_end(iy) - ly.owned_begin(iy));
        detect(models.rdn(), in, owned - cv::Point(x0, y0), threshold, mask0(owned), times,
               prob.empty() ? cv::Mat() : prob(owned), alternative_prob.empty() ? cv::Mat() : alternative_prob(owned));
      }
    }
  };
  if (single) kept = build_inputs(image, 0, ly.end[0], 0, lx.end[0], t);
  if (branches > 1) {
    run_side_by_side({[&] { detect_canvas(*detector, worker_times[0]); },
                      [&] { kept_ihat = reconstruct(models_.rrn_beside(), kept, worker_times[1], opt.mirror_average); }});
  } else {
    detect_canvas(*detector, t);
  }
  // An observer that says stop (a dry image, wet_gate.h) ends the pass here: the mask empty, no
  // image (the caller writes the input).
  if (detection.observe &&
      detection.observe(prob(cv::Rect(0, 0, W, H)), alternative_prob.empty() ? cv::Mat() : alternative_prob(cv::Rect(0, 0, W, H)))) {
    res.mask = cv::Mat::zeros(H, W, CV_8U);
    for (const StageTimes& w : worker_times) t += w;  // the detector and the 3RN beside it ran
    return res;
  }
  if (detection.route) {
    // The router reads the first detector's map; another detector it chooses runs next on the
    // same inputs, on all the threads (the 3RN beside the first is shared: the models'
    // reconstruction is the same whichever detector decides). Measured on a 1280x720
    // photograph, two threads: that beat running it beside the 3RN on one thread, after the
    // first detector (docs/RESULTS.md 4.34).
    auto clock = Clock::now();
    Models* chosen = detection.route(prob(cv::Rect(0, 0, W, H)));
    prob.release();
    t.router += lap_ms(clock);
    if (chosen != detector) {
      detector = chosen;
      threshold = opt.threshold.value_or(detector->info().threshold);
      if (route_reads_alternative && !alternative_prob.empty()) {
        // The first detector's graph computed the alternative's map beside its own, bit for bit
        // what the alternative's graph computes (model.h): thresholded, not run again.
        clock = Clock::now();
        threshold_mask(alternative_prob, threshold, mask0);
        t.mask += lap_ms(clock);
      } else {
        mask0.setTo(0);
        // A map the main graph computed for an observer is not the chosen folder's: its graph
        // has one output.
        alternative_prob.release();
        detect_canvas(*detector, t);
      }
    }
    alternative_prob.release();
  }
  const int k = opt.dilation.value_or(detector->info().dilation);
  // The fill's area is the deciding detector's (a routed image: the alternative's), at this scale.
  const int fill_area_given = opt.surround_fill_area.value_or(detector->info().surround_fill_area);
  const int fill_area = detection.scale > 0
                            ? surround_fill_area_at_scale(fill_area_given, detection.image_size, detection.scale)
                            : fill_area_given;
  const int fill_rim = detection.scale > 0
                           ? surround_fill_rim_at_scale(opt.surround_fill_rim, detection.image_size, detection.scale)
                           : opt.surround_fill_rim;
  auto clock = Clock::now();
  // The deciding detector's growth (checked by run()), or the option's.
  const double growth = grow_large_drops ? opt.large_drop_growth.value_or(detector->info().large_drop_growth) : 0.0;
  cv::Mat mask = dilate_mask_by_size(mask0, k, growth);
  mask0.release();
  const bool reconstruct_now = !gate || gate(mask(cv::Rect(0, 0, W, H)));
  t.mask += lap_ms(clock);
  if (!reconstruct_now) {
    res.mask = mask(cv::Rect(0, 0, W, H)) * 255;
    return res;
  }
  res.reconstructed_pixels = canvas_pixels * (opt.mirror_average ? 2 : 1);
  Models& rec = reconstruction ? reconstruction() : models_;  // pads as the main models do (large_drop_models)

  // Pass 2: reconstruction, blend, refinement; tile outputs blended into a strip of rows
  // that is finished (quantised into the output) as soon as no later tile row reaches it.
  res.image.create(H, W, image.type());
  if (opt.keep_float) res.rgb.create(H, W, CV_32FC3);
  cv::Mat strip;  // rows [strip_y0, strip_y0 + strip.rows) of the padded canvas
  int strip_y0 = 0;
  // Tiled, the mask as the detector found it, which each tile's fill starts from (below).
  const cv::Mat found_mask = single ? cv::Mat() : mask.clone();
  for (int iy = 0; iy < ly.count(); ++iy) {
    const int y0 = ly.begin[iy], y1 = ly.end[iy];
    {
      clock = Clock::now();
      cv::Mat next(y1 - y0, Wp, CV_32FC3, cv::Scalar::all(0));
      if (!strip.empty() && strip_y0 + strip.rows > y0) {
        const int carried = strip_y0 + strip.rows - y0;
        strip.rowRange(y0 - strip_y0, strip.rows).copyTo(next.rowRange(0, carried));
      }
      strip = next;
      strip_y0 = y0;
      t.output += lap_ms(clock);
    }
    std::vector<float> wy(y1 - y0);
    for (int y = y0; y < y1; ++y) wy[y - y0] = ly.weight(iy, y);
    for (int ix = 0; ix < lx.count(); ++ix) {
      const int x0 = lx.begin[ix], x1 = lx.end[ix];
      TileInputs in = single ? std::move(kept) : build_inputs(image, y0, y1, x0, x1, t);
      // 3RN (already run beside the RDN for a single tile on two threads).
      // A single tile whose 3RN did not run beside its RDN (a gated pass, or one thread) uses the
      // same half-thread session: the all-thread 3RN session is made only for tiled images, so a
      // coarse pass creates no sessions beyond those its models load with (it runs on a
      // ninth-size copy, where half the threads cost little).
      std::vector<float> ihat = !kept_ihat.empty() ? std::move(kept_ihat)
                                                   : reconstruct(single ? rec.rrn_beside() : rec.rrn(), in, t, opt.mirror_average);
      const size_t plane = static_cast<size_t>(in.h) * in.w;
      clock = Clock::now();
      // B = M * Ihat + (1 - M) * R with M in {0, 1} is exactly a choice between the two
      // (as in numpy: 1 * a + 0 * b == a for finite values).
      std::vector<float>& blend = ihat;
      // The tile's own copy of the detector's mask in its window: the fill's parts grow into their
      // rims there (surround_fill.h), each tile from the mask as found, so that no tile sees
      // another's growth; the final mask takes the growth of the tile that owns each pixel.
      const cv::Rect window(x0, y0, in.w, in.h);
      cv::Mat tile_mask = single ? mask : found_mask(window).clone();
      res.surround_filled += fill_small_drops_from_surround(in.r.data(), tile_mask, fill_area, opt.surround_fill_mad,
                                                            ihat, nullptr, fill_rim);
      if (!single) {
        const cv::Rect owned(lx.owned_begin(ix), ly.owned_begin(iy), lx.owned_end(ix) - lx.owned_begin(ix),
                             ly.owned_end(iy) - ly.owned_begin(iy));
        tile_mask(owned - window.tl()).copyTo(mask(owned));
      }
      for (int y = 0; y < in.h; ++y) {
        const unsigned char* mrow = tile_mask.ptr<unsigned char>(y);
        for (int c = 0; c < 3; ++c) {
          float* b = blend.data() + c * plane + static_cast<size_t>(y) * in.w;
          const float* r = in.r.data() + c * plane + static_cast<size_t>(y) * in.w;
          for (int x = 0; x < in.w; ++x) {
            if (!mrow[x]) b[x] = r[x];
          }
        }
      }
      t.blend += lap_ms(clock);
      std::vector<float> out(3 * plane);
      if (opt.mirror_average) {
        run_mirror_averaged(rec.rfn(), {blend.data()}, {3}, in.h, in.w, 3, out.data());
      } else {
        rec.rfn().run({blend.data()}, in.h, in.w, out.data());
      }
      clamp_all(out);
      t.rfn += lap_ms(clock);
      std::vector<float> wx(in.w);
      for (int x = x0; x < x1; ++x) wx[x - x0] = lx.weight(ix, x);
      for (int y = 0; y < in.h; ++y) {
        if (wy[y] == 0.0f) continue;
        float* dst = strip.ptr<float>(y) + 3 * static_cast<size_t>(x0);
        const size_t row = static_cast<size_t>(y) * in.w;
        for (int x = 0; x < in.w; ++x) {
          const float w = wy[y] * wx[x];
          if (w == 0.0f) continue;
          for (int c = 0; c < 3; ++c) dst[3 * x + c] += w * out[c * plane + row + x];
        }
      }
      t.output += lap_ms(clock);
    }
    // Rows before the next tile row's first row are final.
    clock = Clock::now();
    const int done_end = std::min(iy + 1 < ly.count() ? ly.begin[iy + 1] : y1, H);
    if (done_end > y0) {
      const cv::Mat rows = strip(cv::Rect(0, 0, W, done_end - y0));
      store_rgb_float(rows, res.image, y0);
      if (opt.keep_float) {
        cv::Mat dst = res.rgb.rowRange(y0, done_end);
        rows.copyTo(dst);
        for (int y = 0; y < dst.rows; ++y) {
          float* p = dst.ptr<float>(y);
          for (int x = 0; x < 3 * W; ++x) p[x] = clamp01(p[x]);
        }
      }
    }
    t.output += lap_ms(clock);
  }
  clock = Clock::now();
  copy_alpha(image, res.image);
  for (const StageTimes& w : worker_times) t += w;  // busy time of the side-by-side work
  res.mask = mask(cv::Rect(0, 0, W, H)) * 255;
  t.output += lap_ms(clock);
  return res;
}

}  // namespace raindrop::removal
