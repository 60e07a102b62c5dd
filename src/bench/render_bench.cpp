// raindrop-bench render: how long the renderer takes, what each effect costs, and what each
// quality knob buys. Markdown tables on stdout, progress on stderr.
#include "render_bench.h"

#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <functional>
#include <iomanip>
#include <iostream>
#include <memory>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <unistd.h>

#include <CLI/CLI.hpp>
#include <opencv2/core.hpp>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "../cli/options.h"
#include "bench_util.h"
#include "raindrop/common/error.h"
#include "raindrop/common/image_io.h"
#include "raindrop/common/rng.h"
#include "raindrop/common/demo.h"
#include "raindrop/render/framing.h"
#include "raindrop/render/inputs.h"
#include "raindrop/render/render_job.h"
#include "raindrop/render/renderer.h"
#include "raindrop/render/scene.h"
#include "raindrop/render/sensor.h"
#include "raindrop/render/veil.h"

namespace raindrop {
namespace fs = std::filesystem;
using bench::mean;
using bench::median;
using bench::now_ms;

namespace {

struct Input {
  fs::path png;                     // decoded in the timing table, as the renderer would
  std::optional<Camera> calibration;
  std::string description;
};

// Runs `body` with exactly `threads` worker threads (TBB and Embree included).
template <class F>
void with_threads(int threads, F&& body) {
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<size_t>(threads));
  tbb::task_arena arena(threads);
  arena.execute(body);
}

SceneConfig paper_with_70_drops() {
  SceneConfig c = scene_preset("paper");
  c.drop_count = {70, 70};
  return c;
}

// The camera the issue states its speed targets with: a lens at f/2 (the scene's focal length,
// 5 mm unless it says otherwise; focused on the street), the glass at 10 cm; no disk blur (the
// lens defocuses the drops).
SceneConfig at_issue_camera(SceneConfig c) {
  c.lens.enabled = true;
  c.blur.enabled = false;
  c.lens.f_number = {2, 2};
  c.glass_distance_cm = {10, 10};
  return c;
}
const char* const kPaperAtIssueCamera = "paper (70 drops) at f/2, glass 10 cm";

std::vector<SceneSample> scenes_for(const SceneConfig& config, const Camera& cam, int frames) {
  std::vector<SceneSample> s;
  for (int i = 0; i < frames; ++i) {
    Rng rng(1000 + i);
    s.push_back(sample_scene(config, cam, rng));
  }
  return s;
}

// Median render-core time (Embree build + trace + blur + compose) over the scenes, frames
// one after another, each using all `threads`.
// `blur`, if given: the median of the blur stage alone (for the thin-lens camera's layered
// path, the compositing of the layers).
double core_ms(const Frame& frame, const SceneConfig& config, const std::vector<SceneSample>& scenes, int threads,
               int repeats, std::vector<RenderedFrame>* outputs = nullptr, double* blur = nullptr) {
  std::vector<double> times, blur_times;
  with_threads(threads, [&] {
    render_frame(frame.clean, frame.camera, config, scenes[0]);  // warm-up
    for (int r = 0; r < repeats; ++r) {
      for (size_t i = 0; i < scenes.size(); ++i) {
        RenderedFrame f = render_frame(frame.clean, frame.camera, config, scenes[i]);
        times.push_back(f.timings.core_ms());
        blur_times.push_back(f.timings.blur_ms);
        if (outputs && r == 0) outputs->push_back(std::move(f));
      }
    }
  });
  if (blur) *blur = median(blur_times);
  return median(times);
}

// The same for two settings, frame by frame in turn, so that a change of the machine's load
// falls on both alike: their ratio is what the two settings cost, not when each ran. Also
// the processor time of each render (all threads), which other jobs on the machine inflate
// less than the wall time.
struct PairedTimes {
  double core_ms[2], cpu_ms[2];
};
PairedTimes paired_core_ms(const Frame& frame, const SceneConfig* configs[2], const std::vector<SceneSample>& scenes,
                           int threads, int repeats, std::vector<RenderedFrame> outputs[2]) {
  std::vector<double> wall[2], cpu[2];
  with_threads(threads, [&] {
    for (int k = 0; k < 2; ++k) render_frame(frame.clean, frame.camera, *configs[k], scenes[0]);  // warm-up
    for (int r = 0; r < repeats; ++r) {
      for (size_t i = 0; i < scenes.size(); ++i) {
        for (int k = 0; k < 2; ++k) {
          const std::clock_t c0 = std::clock();
          RenderedFrame f = render_frame(frame.clean, frame.camera, *configs[k], scenes[i]);
          cpu[k].push_back(1000.0 * static_cast<double>(std::clock() - c0) / CLOCKS_PER_SEC);
          wall[k].push_back(f.timings.core_ms());
          if (r == 0) outputs[k].push_back(std::move(f));
        }
      }
    }
  });
  return {{median(wall[0]), median(wall[1])}, {median(cpu[0]), median(cpu[1])}};
}

// The render core's stages on the paper preset at 2048x1024: each frame's minimum over the
// repeats (the least disturbed run of that frame: on a shared machine the load changes
// between runs by more than a change of the code does), then their mean over the frames.
void core_table(const Input& input, int frames, int repeats) {
  const cv::Size size(2048, 1024);
  std::cout << "\n### Render core by stage (" << size.width << "x" << size.height << ", paper scene with 70 drops)\n\n"
            << "Each frame rendered " << repeats << " times in turn with the others; per frame the fastest of its "
            << repeats << " renders, then the mean over the " << frames << " frames.\n\n"
            << "| threads | accel ms | trace ms | blur ms | compose ms | core ms |\n|---|---|---|---|---|---|\n";
  const Frame frame = make_frame(read_rgb8(input.png, false), input.calibration, size);
  const SceneConfig config = paper_with_70_drops();
  const std::vector<SceneSample> scenes = scenes_for(config, frame.camera, frames);
  for (int threads : {1, 2}) {
    std::cerr << "bench render: core by stage, " << threads << " thread(s)\n";
    std::vector<FrameTimings> best(scenes.size());
    with_threads(threads, [&] {
      render_frame(frame.clean, frame.camera, config, scenes[0]);  // warm-up
      for (int r = 0; r < repeats; ++r) {
        for (size_t i = 0; i < scenes.size(); ++i) {
          const FrameTimings t = render_frame(frame.clean, frame.camera, config, scenes[i]).timings;
          if (r == 0 || t.core_ms() < best[i].core_ms()) best[i] = t;
        }
      }
    });
    auto mean_of = [&](double FrameTimings::*stage) {
      double sum = 0;
      for (const FrameTimings& t : best) sum += t.*stage;
      return sum / static_cast<double>(best.size());
    };
    double core = 0;
    for (const FrameTimings& t : best) core += t.core_ms() / static_cast<double>(best.size());
    std::cout << std::flush;
    std::printf("| %d | %.1f | %.1f | %.1f | %.1f | %.1f |\n", threads, mean_of(&FrameTimings::accel_ms),
                mean_of(&FrameTimings::trace_ms), mean_of(&FrameTimings::blur_ms), mean_of(&FrameTimings::compose_ms), core);
    std::fflush(stdout);
  }
}

// One scene's frames end to end, decode, render and PNG files, on `threads` threads, against
// the same loop with decode and encode only (the I/O floor): `frames` frames at a time, the
// wall time per frame, medians over `repeats`. The files are what raindrop-render writes:
// rainy, clean, mask, and where the scene has a lens the coverage (alpha16, render_job.h).
struct EndToEnd {
  double e2e = 0, floor = 0;                         // ms per frame, medians
  double decode = 0, trace = 0, blur = 0, encode = 0;  // per-frame latencies, means
  double drop_px = 0, coverage = 0;                  // means
};

EndToEnd end_to_end(const Input& input, const SceneConfig& config, const cv::Size& size, int threads, int frames,
                    int repeats, const fs::path& tmp) {
  std::vector<double> wall_full, wall_floor;
  std::vector<double> decode(frames), trace(frames), blur(frames), encode(frames);
  std::vector<cv::Mat> rainy(frames), clean(frames), mask(frames), alpha(frames);
  std::vector<std::int64_t> px(frames);
  std::vector<double> coverage(frames);
  std::vector<std::string> clean_bytes(frames);  // per frame, the input's bytes written as its clean image, if any
  auto write_clean = [&](int i, const cv::Mat& image, const fs::path& path) {
    if (clean_bytes[i].empty()) {
      write_image_atomic(image, path);
    } else {
      write_text_atomic(clean_bytes[i], path);
    }
  };
  // Warm-up: loads the image plugins and creates the Embree device outside the timings.
  with_threads(threads, [&] {
    const Frame f = make_frame(read_rgb8(input.png, false), input.calibration, size);
    Rng rng(1);
    const RenderedFrame out = render_frame(f.clean, f.camera, config, sample_scene(config, f.camera, rng));
    write_image_atomic(out.rainy, tmp / "warmup.png");
  });
  for (int r = 0; r < repeats; ++r) {
    with_threads(threads, [&] {
      double t0 = now_ms();
      tbb::parallel_for(0, frames, 1, [&](int i) {
        const double a = now_ms();
        std::string input_png;
        const cv::Mat rgb = read_rgb8(input.png, false, 16, &input_png);
        const Frame f = make_frame(rgb, input.calibration, size);
        const double b = now_ms();
        Rng rng(1000 + i);
        const SceneSample scene = sample_scene(config, f.camera, rng);
        const RenderedFrame out = render_frame(f.clean, f.camera, config, scene);
        const double c = now_ms();
        const std::string stem = "t" + std::to_string(i);
        write_image_atomic(out.rainy, tmp / (stem + "_rainy.png"));
        // As raindrop-render writes it: the input file's bytes where the frame is the input as
        // it was (render_job.cpp), else encoded.
        clean_bytes[i] = frame_is_stored_input(rgb, f, input_png) && out.clean.empty() ? input_png : std::string();
        write_clean(i, f.clean, tmp / (stem + "_clean.png"));
        write_image_atomic(out.mask, tmp / (stem + "_mask.png"));
        if (config.lens.enabled) {
          alpha[i] = alpha16(out);
          write_image_atomic(alpha[i], tmp / (stem + "_alpha.png"));
        }
        const double d = now_ms();
        decode[i] = b - a;
        trace[i] = out.timings.accel_ms + out.timings.trace_ms;
        blur[i] = out.timings.blur_ms;
        encode[i] = d - c;
        rainy[i] = out.rainy;
        clean[i] = f.clean;
        mask[i] = out.mask;
        px[i] = out.stats.drop_pixels;
        coverage[i] = out.coverage();
      });
      wall_full.push_back((now_ms() - t0) / frames);
      t0 = now_ms();
      tbb::parallel_for(0, frames, 1, [&](int i) {
        std::string input_png;  // read as the loop above reads it (the bytes kept): the same work
        const Frame f = make_frame(read_rgb8(input.png, false, 16, &input_png), input.calibration, size);
        (void)f;
        const std::string stem = "f" + std::to_string(i);
        write_image_atomic(rainy[i], tmp / (stem + "_rainy.png"));
        write_clean(i, clean[i], tmp / (stem + "_clean.png"));
        write_image_atomic(mask[i], tmp / (stem + "_mask.png"));
        if (config.lens.enabled) write_image_atomic(alpha[i], tmp / (stem + "_alpha.png"));
      });
      wall_floor.push_back((now_ms() - t0) / frames);
    });
  }
  EndToEnd e;
  e.e2e = median(wall_full);
  e.floor = median(wall_floor);
  e.decode = mean(decode);
  e.trace = mean(trace);
  e.blur = mean(blur);
  e.encode = mean(encode);
  for (auto p : px) e.drop_px += static_cast<double>(p) / frames;
  e.coverage = mean(coverage);
  return e;
}

void time_table(const Input& input, const std::vector<cv::Size>& sizes, int frames, int repeats, const fs::path& tmp) {
  std::cout << "\n### Time per frame (paper scene, 70 drops)\n\n"
            << "Decode = read + crop/resize; trace includes building the Embree scene; encode = the three "
               "images written as raindrop-render writes them (rainy and mask encoded as PNG; clean too, "
               "except where the frame is the input PNG as it was: then its bytes). Stage columns are per-frame latencies inside a run that keeps all "
               "threads busy with " << frames << " frames; *end to end* is the run's wall time per frame; the "
               "*I/O floor* runs the same loop with decode and encode only (same images); *core alone* is "
               "trace + blur + compose with all threads on one frame at a time.\n\n"
            << "| size | threads | decode ms | trace ms | blur ms | encode ms | end to end ms | I/O floor ms | "
               "end to end / floor | core alone ms | drop px | coverage |\n"
            << "|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  const SceneConfig config = paper_with_70_drops();
  for (const cv::Size& size : sizes) {
    for (int threads : {1, 2}) {
      std::cerr << "bench render: time table " << size.width << "x" << size.height << ", " << threads << " thread(s)\n";
      const EndToEnd e = end_to_end(input, config, size, threads, frames, repeats, tmp);
      Frame frame = make_frame(read_rgb8(input.png, false), input.calibration, size);
      const double core = core_ms(frame, config, scenes_for(config, frame.camera, frames), threads, repeats);
      std::printf("| %dx%d | %d | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f | %.2f | %.1f | %.0f | %.1f%% |\n", size.width,
                  size.height, threads, e.decode, e.trace, e.blur, e.encode, e.e2e, e.floor, e.e2e / e.floor, core,
                  e.drop_px, 100 * e.coverage);
      std::fflush(stdout);
    }
  }
}

// Every effect the renderer has, on everywhere: the full simulation auto is measured against.
void everything_on(SceneConfig& c) {
  c.fresnel.enabled = c.dispersion.enabled = c.gravity.enabled = true;
  c.dispersion.automatic = c.gravity.automatic = false;
  c.tir = TirMode::Trace;
  c.samples_per_pixel = 4;
  c.supersample = Supersample::All;
}

// The same left to the scene's physics (effect_policy.h).
void make_auto(SceneConfig& c) {
  c.dispersion.automatic = c.gravity.automatic = true;
  c.supersample = Supersample::Auto;
}

void add_error(const cv::Mat& test, const cv::Mat& ref, const cv::Mat& region, double* sq, double* n, double* worst);

void effects_table(const Input& input, int frames, int repeats) {
  const cv::Size size(2048, 1024);
  std::cout << "\n### What each effect costs (2048x1024, 2 threads, render core per frame)\n\n"
            << "Effects are template parameters of the tracing kernel or separate passes: an effect a scene "
               "does not name is not in the code that runs. *paper (again)* repeats the first row at the end "
               "to show the noise.\n\n"
            << "| scene | core ms | vs paper | drop px |\n|---|---|---|---|\n";
  const Frame frame = make_frame(read_rgb8(input.png, false), input.calibration, size);
  const SceneConfig paper = paper_with_70_drops();
  struct Row {
    std::string name;
    std::function<void(SceneConfig&)> edit;
  };
  const std::vector<Row> rows = {
      {"paper (refraction, dark band, blur)", [](SceneConfig&) {}},
      {"paper without blur", [](SceneConfig& c) { c.blur.enabled = false; }},
      {"+ fresnel", [](SceneConfig& c) { c.fresnel.enabled = true; }},
      {"+ dispersion (3 paths per pixel)", [](SceneConfig& c) { c.dispersion.enabled = true; }},
      {"+ gravity (ellipsoidal caps)", [](SceneConfig& c) { c.gravity.enabled = true; }},
      {"+ irregular outlines (peak 0.1-0.35, 6 modes; searched caps)", [](SceneConfig& c) {
         c.outline.enabled = true;
         c.outline.peak_deviation = {0.1, 0.35};
       }},
      {"+ irregular outlines as mesh-64-smooth", [](SceneConfig& c) {
         c.outline.enabled = true;
         c.outline.peak_deviation = {0.1, 0.35};
         c.geometry = GeometryOptions::parse("mesh-64-smooth");
       }},
      {"+ trails (defaults; most of these large drops slide)", [](SceneConfig& c) { c.trails.enabled = true; }},
      {"+ traced internal reflection", [](SceneConfig& c) { c.tir = TirMode::Trace; }},
      {"+ 4 spp at drop edges", [](SceneConfig& c) { c.samples_per_pixel = 4; }},
      {"+ all of the above", [](SceneConfig& c) {
         c.fresnel.enabled = c.dispersion.enabled = c.gravity.enabled = true;
         c.tir = TirMode::Trace;
         c.samples_per_pixel = 4;
       }},
      {"+ all of the above, 4 spp in every drop pixel (everything on)", [](SceneConfig& c) { everything_on(c); }},
      {"+ all of the above, auto (dispersion, gravity, supersampling)", [](SceneConfig& c) {
         everything_on(c);
         make_auto(c);
       }},
      {"paper (again)", [](SceneConfig&) {}},
  };
  double base = 0;
  for (const Row& row : rows) {
    std::cerr << "bench render: effects: " << row.name << "\n";
    SceneConfig c = paper;
    row.edit(c);
    std::vector<RenderedFrame> out;
    const double ms = core_ms(frame, c, scenes_for(c, frame.camera, frames), 2, repeats, &out);
    if (base == 0) base = ms;
    double px = 0;
    for (const auto& f : out) px += static_cast<double>(f.stats.drop_pixels) / out.size();
    std::printf("| %s | %.1f | %.2fx | %.0f |\n", row.name.c_str(), ms, ms / base, px);
    std::fflush(stdout);
  }
  // The camera's noise and JPEG (sensor.h) run after the render, on the rainy image only, in the
  // job; a scene without "sensor" runs neither.
  std::cout << "\n*sensor* (noise and JPEG on the rainy image, after the render core; one thread, the "
               "frame above, median of " << repeats << "):\n\n| sensor | ms per frame | vs the paper core |\n|---|---|---|\n";
  const std::vector<std::pair<std::string, SensorSample>> sensors = {
      {"noise (sigma 2)", {2.0, 0}}, {"JPEG quality 80", {0.0, 80}}, {"noise and JPEG 80", {2.0, 80}}};
  for (const auto& [name, sensor] : sensors) {
    std::vector<double> times;
    for (int r = 0; r < std::max(repeats, 3); ++r) {
      cv::Mat rainy = frame.clean.clone();
      const double t0 = bench::now_ms();
      apply_sensor(rainy, sensor, static_cast<std::uint64_t>(r));
      times.push_back(bench::now_ms() - t0);
    }
    std::printf("| %s | %.1f | %.2fx |\n", name.c_str(), median(times), median(times) / base);
  }
  // The wet glass' veil (veil.h), also after the render core on the rainy image only: the fast
  // blur (averaged down, blurred, interpolated back) at three lobe widths, against the exact
  // full-resolution Gaussian (its kernel spans 8 sigma: seconds per frame, run once).
  std::cout << "\n*veil* (on the rainy image, after the render core; optical depth 0.02; one thread, the frame "
               "above, median of " << std::max(repeats, 3) << "; error of the fast blur against the exact one over the "
               "whole frame, 8-bit levels):\n\n| spread | sigma px | fast ms | vs the paper core | exact ms | RMSE | max |\n"
               "|---|---|---|---|---|---|---|\n";
  for (const double spread : {2.0, 5.0, 10.0}) {
    VeilSample veil;
    veil.optical_depth = 0.02;
    veil.spread_deg = spread;
    veil.sigma_px = frame.camera.fx * std::tan(spread * M_PI / 180.0);
    std::vector<double> times;
    cv::Mat fast;
    for (int r = 0; r < std::max(repeats, 3); ++r) {
      fast = frame.clean.clone();
      const double t0 = bench::now_ms();
      apply_veil(fast, veil);
      times.push_back(bench::now_ms() - t0);
    }
    cv::Mat exact = frame.clean.clone();
    const double t0 = bench::now_ms();
    apply_veil(exact, veil, {}, VeilMethod::Exact);
    const double exact_ms = bench::now_ms() - t0;
    double sq = 0, n = 0, worst = 0;
    add_error(fast, exact, cv::Mat(exact.size(), CV_8U, cv::Scalar(255)), &sq, &n, &worst);
    std::printf("| %.0f deg | %.0f | %.1f | %.2fx | %.0f | %.3f | %.0f |\n", spread, veil.sigma_px, median(times),
                median(times) / base, exact_ms, std::sqrt(sq / n), worst);
    std::fflush(stdout);
  }
  // Highlights (highlights.h) act where the lens spreads light, so they are measured on
  // lens-cover, with and without, frame by frame in turn (a change of the machine's load falls
  // on both alike), as the wall time of the whole render_frame call: it includes the check for
  // clipped pixels, which the stage timings above do not. Then the same frame dimmed below the
  // threshold, where the effect is skipped.
  std::cout << "\n*highlights* (lens-cover, the frame above; render_frame wall time, 2 threads, median of "
            << repeats << " x " << frames << " frames, in turn):\n\n"
               "| frame | without ms | with highlights (gain 8) ms | ratio |\n|---|---|---|---|\n";
  cv::Mat dim;
  frame.clean.convertTo(dim, -1, 200.0 / 255.0);
  for (int dimmed = 0; dimmed < 2; ++dimmed) {
    const cv::Mat& clean = dimmed ? dim : frame.clean;
    SceneConfig configs[2] = {scene_preset("lens-cover"), scene_preset("lens-cover")};
    configs[0].highlights.enabled = false;
    configs[1].highlights.enabled = true;
    configs[1].highlights.gain = {8, 8};
    const std::vector<SceneSample> scenes = scenes_for(configs[1], frame.camera, frames);
    std::vector<double> wall[2];
    with_threads(2, [&] {
      for (int k = 0; k < 2; ++k) render_frame(clean, frame.camera, configs[k], scenes[0]);  // warm-up
      for (int r = 0; r < repeats; ++r) {
        for (const SceneSample& scene : scenes) {
          for (int k = 0; k < 2; ++k) {
            const double t0 = bench::now_ms();
            const RenderedFrame f = render_frame(clean, frame.camera, configs[k], scene);
            wall[k].push_back(bench::now_ms() - t0);
          }
        }
      }
    });
    cv::Mat brightest;
    cv::Mat channels[3];
    cv::split(clean, channels);
    cv::max(cv::max(channels[0], channels[1]), channels[2], brightest);
    // The codes at or above the threshold (a fraction of full scale as stored): what the lift changes.
    const double lifted = 100.0 * cv::countNonZero(brightest >= 255.0 * configs[1].highlights.threshold) /
                          static_cast<double>(brightest.total());
    std::printf("| %s (%.2f%% of pixels at or above the threshold) | %.1f | %.1f | %.2fx |\n",
                dimmed ? "dimmed to 200/255: skipped" : "as it is", lifted, median(wall[0]), median(wall[1]),
                median(wall[1]) / median(wall[0]));
    std::fflush(stdout);
  }
  // Focus on the glass (background_defocus.h): glass-droplets as it is against the same samples
  // focused on the background, in turn. The difference is the street's own blur (its stage
  // time is the first column of the second row) and the drops now sharp instead of spread.
  std::cout << "\n*focus* (glass-droplets, the frame above; render_frame wall time, 2 threads, median of " << repeats
            << " x " << frames << " frames, in turn):\n\n"
               "| focus | street's circle px (median) | street blur ms | render ms | ratio |\n|---|---|---|---|---|\n";
  {
    SceneConfig configs[2] = {scene_preset("glass-droplets"), scene_preset("glass-droplets")};
    configs[0].lens.focus = SceneConfig::Focus::Background;
    const std::vector<SceneSample> focused = scenes_for(configs[1], frame.camera, frames);
    std::vector<double> wall[2], blur_ms, circles;
    with_threads(2, [&] {
      for (int k = 0; k < 2; ++k) render_frame(frame.clean, frame.camera, configs[k], focused[0]);  // warm-up
      for (int r = 0; r < repeats; ++r) {
        for (const SceneSample& scene : focused) {
          for (int k = 0; k < 2; ++k) {
            SceneSample s = scene;
            if (k == 0) s.focus_distance_cm = 0;  // the same drops and lens, focused on the street
            const double t0 = bench::now_ms();
            const RenderedFrame f = render_frame(frame.clean, frame.camera, configs[k], s);
            wall[k].push_back(bench::now_ms() - t0);
            if (k == 1) {
              blur_ms.push_back(f.timings.background_ms);
              circles.push_back(s.background_coc_px(frame.camera.fx));
            }
          }
        }
      }
    });
    std::printf("| background | 0 | 0 | %.1f | 1.00x |\n", median(wall[0]));
    std::printf("| glass | %.1f | %.1f | %.1f | %.2fx |\n", median(circles), median(blur_ms), median(wall[1]),
                median(wall[1]) / median(wall[0]));
    std::fflush(stdout);
  }
}

// Errors of `test` against `ref` over pixels in either mask.
struct Error8 {
  double mask_disagree = 0;  // pixels in one mask only, as a fraction of the reference mask
  double rmse = 0, psnr = 0, max_abs = 0;
};

// Adds the squared 8-bit differences of two renders over `region` (non-zero pixels) to *sq,
// the values counted to *n, and raises *worst to the largest absolute difference anywhere.
void add_error(const cv::Mat& test, const cv::Mat& ref, const cv::Mat& region, double* sq, double* n, double* worst) {
  cv::Mat diff;
  cv::absdiff(test, ref, diff);
  diff.convertTo(diff, CV_64FC3);
  cv::Mat sqd = diff.mul(diff);
  const cv::Scalar s = cv::sum(sqd.setTo(0, region == 0));
  *sq += s[0] + s[1] + s[2];
  *n += 3.0 * cv::countNonZero(region);
  double lo, hi;
  cv::minMaxLoc(diff.reshape(1), &lo, &hi);
  *worst = std::max(*worst, hi);
}

Error8 compare(const std::vector<RenderedFrame>& test, const std::vector<RenderedFrame>& ref) {
  double sq = 0, n = 0, worst = 0, disagree = 0, ref_px = 0;
  for (size_t i = 0; i < ref.size(); ++i) {
    cv::Mat either = test[i].mask | ref[i].mask, one = test[i].mask ^ ref[i].mask;
    disagree += cv::countNonZero(one);
    ref_px += cv::countNonZero(ref[i].mask);
    add_error(test[i].rainy, ref[i].rainy, either, &sq, &n, &worst);
  }
  Error8 e;
  e.mask_disagree = ref_px > 0 ? disagree / ref_px : 0;
  e.rmse = n > 0 ? std::sqrt(sq / n) : 0;
  e.psnr = e.rmse > 0 ? 20 * std::log10(255.0 / e.rmse) : 99.0;
  e.max_abs = worst;
  return e;
}

void accuracy_table(const Input& input, int frames, int repeats) {
  const cv::Size size(1024, 512);
  std::cout << "\n### Accuracy against time (1024x512, 2 threads, paper scene with 70 drops, " << frames
            << " frames)\n\n"
            << "Each row changes one knob of the default (exact caps, 1 sample per pixel, antialiased disk "
               "blur). Errors are over the pixels inside either mask, against the most accurate setting: exact "
               "caps with 64 samples in every drop pixel (geometry and sampling rows), or the antialiased disk "
               "on the same traced image (blur rows). RMSE and max in 8-bit levels; *mask* = pixels in one "
               "mask only, relative to the reference mask.\n\n"
            << "| knob | setting | core ms | RMSE | PSNR dB | max | mask |\n|---|---|---|---|---|---|---|\n";
  const Frame frame = make_frame(read_rgb8(input.png, false), input.calibration, size);
  const SceneConfig base = paper_with_70_drops();
  const std::vector<SceneSample> scenes = scenes_for(base, frame.camera, frames);
  auto run = [&](const SceneConfig& c, std::vector<RenderedFrame>* out) { return core_ms(frame, c, scenes, 2, repeats, out); };

  std::cerr << "bench render: accuracy reference (64 spp everywhere)\n";
  SceneConfig ref_config = base;
  ref_config.samples_per_pixel = 64;
  ref_config.supersample = Supersample::All;
  std::vector<RenderedFrame> reference;
  const double ref_ms = core_ms(frame, ref_config, scenes, 2, 1, &reference);
  std::printf("| reference | exact, 64 spp in all drop pixels | %.1f | 0 | - | 0 | 0 |\n", ref_ms);

  auto row = [&](const std::string& knob, const std::string& setting, const SceneConfig& c,
                 const std::vector<RenderedFrame>& against) {
    std::cerr << "bench render: accuracy " << knob << " " << setting << "\n";
    std::vector<RenderedFrame> out;
    const double ms = run(c, &out);
    const Error8 e = compare(out, against);
    std::printf("| %s | %s | %.1f | %.2f | %.1f | %.0f | %.2f%% |\n", knob.c_str(), setting.c_str(), ms, e.rmse, e.psnr,
                e.max_abs, 100 * e.mask_disagree);
    std::fflush(stdout);
  };
  for (const char* g : {"exact", "mesh-8-flat", "mesh-16-flat", "mesh-32-flat", "mesh-64-flat", "mesh-16-smooth",
                        "mesh-32-smooth", "mesh-64-smooth", "mesh-128-smooth"}) {
    SceneConfig c = base;
    c.geometry = GeometryOptions::parse(g);
    row("geometry", g, c, reference);
  }
  for (int spp : {4, 16}) {
    for (bool edges : {true, false}) {
      SceneConfig c = base;
      c.samples_per_pixel = spp;
      c.supersample = edges ? Supersample::Edges : Supersample::All;
      row("samples", std::to_string(spp) + " spp " + (edges ? "at drop edges" : "in all drop pixels"), c, reference);
    }
  }
  std::vector<RenderedFrame> aa;
  core_ms(frame, base, scenes, 2, 1, &aa);
  for (BlurMethod m : {BlurMethod::DiskAntialiased, BlurMethod::DiskSpan, BlurMethod::DiskDirect, BlurMethod::Gaussian}) {
    SceneConfig c = base;
    c.blur.method = m;
    row("blur", to_string(m), c, aa);
  }
  {
    SceneConfig c = base;
    c.blur.enabled = false;
    row("blur", "none", c, aa);
  }
}

// "auto" against everything on, on the paper's scene, on windshield-day (small drops seen
// through a thin lens) and on lens-cover (drops a few cm from the lens, far out of focus), and
// supersampling alone on the paper's scene (its dark band black), at the paper's 2048 px and
// at the 512 px training size: time, error over the drop pixels, and what auto skipped.
void auto_table(const Input& input, int frames, int repeats) {
  std::cout << "\n### Effects chosen by physics: auto against everything on (2 threads, " << frames
            << " frames per row)\n\n"
            << "*Everything on*: the scene plus Fresnel, dispersion, gravity, traced internal reflection and 4 samples "
               "in every drop pixel (*paper, 4 spp only*: the paper's scene with 4 samples in every drop pixel); "
               "*auto*: the same with dispersion, gravity and supersampling \"auto\", timed frame "
               "by frame in turn with it (medians; *CPU ms*: processor time of the render, both threads; the paper "
               "scene alone is the yardstick of *vs paper*). Errors "
               "over the pixels inside either render's drops (mask, or coverage above 0.01), in 8-bit levels. "
               "*Skipped*: dispersion and gravity, share of the drops; supersampling, share of the inside drop "
               "pixels (not at an edge) left at one sample.\n\n"
            << "| scene | size | setting | core ms | vs paper | CPU ms | core vs everything on | CPU vs everything on | "
               "RMSE | PSNR dB | max | dispersion skipped | gravity skipped | one sample |\n"
               "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const cv::Size size : {cv::Size(2048, 1024), cv::Size(512, 256)}) {
    const Frame frame = make_frame(read_rgb8(input.png, false), input.calibration, size);
    const double paper_ms =
        core_ms(frame, paper_with_70_drops(), scenes_for(paper_with_70_drops(), frame.camera, frames), 2, repeats);
    for (const char* preset : {"paper", "windshield-day", "lens-cover", "paper, 4 spp only"}) {
      const std::string name = preset;
      SceneConfig on = name.rfind("paper", 0) == 0 ? paper_with_70_drops() : scene_preset(preset);
      if (name == "paper, 4 spp only") {
        on.samples_per_pixel = 4;  // the paper's effects and black dark band, supersampled
        on.supersample = Supersample::All;
      } else {
        everything_on(on);
      }
      SceneConfig automatic = on;
      make_auto(automatic);
      const std::vector<SceneSample> scenes = scenes_for(on, frame.camera, frames);
      std::cerr << "bench render: auto " << preset << " " << size.width << "x" << size.height << "\n";
      const SceneConfig* configs[2] = {&on, &automatic};
      std::vector<RenderedFrame> outputs[2];
      const PairedTimes t = paired_core_ms(frame, configs, scenes, 2, repeats, outputs);
      const std::vector<RenderedFrame>&full = outputs[0], &chosen = outputs[1];
      double sq = 0, n = 0, worst = 0, drops = 0, no_dispersion = 0, no_gravity = 0, one = 0, inside = 0;
      for (size_t i = 0; i < full.size(); ++i) {
        auto covered = [](const RenderedFrame& f) { return f.alpha.empty() ? cv::Mat(f.mask > 0) : cv::Mat(f.alpha > 0.01f); };
        add_error(chosen[i].rainy, full[i].rainy, covered(chosen[i]) | covered(full[i]), &sq, &n, &worst);
        for (const DropEffects& d : chosen[i].effects.drops) {
          drops += 1;
          no_dispersion += !d.dispersion;
          no_gravity += !d.gravity;
        }
        one += static_cast<double>(chosen[i].stats.smooth_pixels);
        inside += static_cast<double>(chosen[i].stats.smooth_pixels + chosen[i].stats.aliasing_pixels);
      }
      const double rmse = n > 0 ? std::sqrt(sq / n) : 0;
      const std::string dims = std::to_string(size.width) + "x" + std::to_string(size.height);
      std::printf("| %s | %s | everything on | %.1f | %.2fx | %.1f | 1.00x | 1.00x | 0 | - | 0 | 0%% | 0%% | 0%% |\n",
                  preset, dims.c_str(), t.core_ms[0], t.core_ms[0] / paper_ms, t.cpu_ms[0]);
      std::printf("| %s | %s | auto | %.1f | %.2fx | %.1f | %.2fx | %.2fx | %.2f | %.1f | %.0f | %.0f%% | %.0f%% | %.0f%% |\n",
                  preset, dims.c_str(), t.core_ms[1], t.core_ms[1] / paper_ms, t.cpu_ms[1], t.core_ms[1] / t.core_ms[0],
                  t.cpu_ms[1] / t.cpu_ms[0], rmse,
                  rmse > 0 ? 20 * std::log10(255.0 / rmse) : 99.0, worst, 100 * no_dispersion / std::max(drops, 1.0),
                  100 * no_gravity / std::max(drops, 1.0), 100 * one / std::max(inside, 1.0));
      std::fflush(stdout);
    }
  }
}

// The thin-lens camera: aperture sampling at 1-256 rays per pixel and the layered fast path
// (and its exact per-drop form), against aperture sampling with 256 rays, on the lens-cover,
// windshield-day and glass-droplets presets (the last focused on its glass: the street's own
// defocus is compared too).
void lens_table(const Input& input, int frames, int repeats, int threads, const cv::Size& size) {
  const Frame frame = make_frame(read_rgb8(input.png, false), input.calibration, size);
  const double paper_ms =
      core_ms(frame, paper_with_70_drops(), scenes_for(paper_with_70_drops(), frame.camera, frames), threads, repeats, nullptr);
  std::cout << "\n### Thin-lens defocus: accuracy against time (" << size.width << "x" << size.height << ", "
            << threads << (threads == 1 ? " thread, " : " threads, ") << frames << " frames per preset, median of "
            << repeats << " repeats for the layered rows and the paper preset)\n\n"
            << "Errors over the pixels where either render has coverage above 0.01, against aperture sampling "
               "with 256 rays per pixel; RMSE and max in 8-bit levels, *coverage* = mean absolute difference "
               "of the coverage (alpha) there. The paper preset's core time on the same frame is the yardstick; "
               "*layers ms* is the layered compositing alone (the rest of the core is the pinhole trace). Paper "
               "preset core on this frame: " << std::fixed << std::setprecision(1) << paper_ms << std::defaultfloat << " ms.\n\n"
            << "| preset | method | core ms | x paper | layers ms | RMSE | PSNR dB | max | coverage |\n"
            << "|---|---|---|---|---|---|---|---|---|\n";
  std::vector<std::string> street;  // the clean images' errors, where the street is out of focus
  auto fixed2 = [](double v) {
    char text[32];
    std::snprintf(text, sizeof text, "%.2f", v);
    return std::string(text);
  };
  // The presets, and the paper's drops at the issue's camera (at_issue_camera).
  for (const std::string& name : {std::string("lens-cover"), std::string("windshield-day"),
                                  std::string(kPaperAtIssueCamera), std::string("glass-droplets")}) {
    const char* preset = name.c_str();
    const SceneConfig fast = name == kPaperAtIssueCamera ? at_issue_camera(paper_with_70_drops()) : scene_preset(name);
    const std::vector<SceneSample> scenes = scenes_for(fast, frame.camera, frames);
    auto with = [&](DefocusMethod method, int samples) {
      SceneConfig c = fast;
      c.lens.method = method;
      c.lens.aperture_samples = samples;
      return c;
    };
    std::cerr << "bench render: lens reference " << preset << "\n";
    std::vector<RenderedFrame> reference;
    const double ref_ms = core_ms(frame, with(DefocusMethod::Aperture, 256), scenes, threads, 1, &reference);
    // Returns whether the row's renders traced drops in focus through the aperture.
    auto row = [&](const std::string& method, const SceneConfig& c, int row_repeats) {
      std::vector<RenderedFrame> out;
      double layers = 0;
      const bool is_reference = c.lens.aperture_samples == 256 && c.lens.method == DefocusMethod::Aperture;
      const double ms = is_reference ? ref_ms : core_ms(frame, c, scenes, threads, row_repeats, &out, &layers);
      if (out.empty()) out = reference;
      double sq = 0, n = 0, worst = 0, cov = 0;
      // A frame the lens was skipped for is the pinhole render: its coverage is its binary mask.
      auto coverage = [](const RenderedFrame& f) {
        if (!f.alpha.empty()) return f.alpha;
        cv::Mat a;
        f.mask.convertTo(a, CV_32F, 1.0 / 255);
        return a;
      };
      for (size_t i = 0; i < reference.size(); ++i) {
        const cv::Mat a = coverage(out[i]), ref = coverage(reference[i]);
        const cv::Mat inside = (a > 0.01f) | (ref > 0.01f);
        add_error(out[i].rainy, reference[i].rainy, inside, &sq, &n, &worst);
        cov += cv::mean(cv::abs(a - ref), inside)[0] * cv::countNonZero(inside);
      }
      const double rmse = n > 0 ? std::sqrt(sq / n) : 0;
      char layers_text[32] = "-";
      if (c.lens.method != DefocusMethod::Aperture) std::snprintf(layers_text, sizeof layers_text, "%.1f", layers);
      std::printf("| %s | %s | %.1f | %.1f | %s | %.2f | %.1f | %.0f | %.3f |\n", preset, method.c_str(), ms,
                  ms / paper_ms, layers_text, rmse, rmse > 0 ? 20 * std::log10(255.0 / rmse) : 99.0, worst,
                  n > 0 ? 3 * cov / n : 0.0);
      std::fflush(stdout);
      // Focus off the street (glass-droplets): the street's own defocus, over the whole frame (a
      // frame without a clean image of its own shows the input there).
      const bool street_defocused =
          std::any_of(reference.begin(), reference.end(), [](const RenderedFrame& f) { return !f.clean.empty(); });
      if (street_defocused && !is_reference) {
        double csq = 0, cn = 0, cworst = 0;
        for (size_t i = 0; i < reference.size(); ++i) {
          const cv::Mat all(frame.camera.height, frame.camera.width, CV_8U, cv::Scalar(255));
          add_error(out[i].clean_or(frame.clean), reference[i].clean_or(frame.clean), all, &csq, &cn, &cworst);
        }
        street.push_back(method + ": RMSE " + fixed2(cn > 0 ? std::sqrt(csq / cn) : 0) + ", max " +
                         std::to_string(static_cast<int>(cworst)));
      }
      return std::any_of(out.begin(), out.end(), [](const RenderedFrame& f) { return f.lens_sampled; });
    };
    const bool in_focus = row("layered (fast path)", fast, repeats);
    row("layered-exact (filter2D per drop)", with(DefocusMethod::LayeredExact, fast.lens.aperture_samples), repeats);
    // Drops in focus are traced through the aperture with the scene's aperture_samples (16):
    // what fewer and more rays cost and give.
    if (in_focus) {
      SceneConfig centre = fast;
      centre.lens.trace_in_focus = false;
      row("layered, drops in focus through the lens' centre", centre, repeats);
      for (int samples : {4, 64}) {
        row("layered, drops in focus through " + std::to_string(samples) + " rays", with(DefocusMethod::Layered, samples),
            repeats);
      }
    }
    for (int samples : {1, 4, 16, 64, 256}) {
      row("aperture, " + std::to_string(samples) + " rays", with(DefocusMethod::Aperture, samples), 1);
    }
  }
  if (!street.empty()) {
    std::cout << "\nglass-droplets is focused on its glass: the street is out of focus too. Its clean image "
                 "(the street alone) against the reference's over the whole frame, in 8-bit levels:\n\n";
    for (const std::string& line : street) std::cout << "- " << line << "\n";
  }
}

}  // namespace

namespace {

struct RenderBenchOptions {
  std::string input_path, shared = "../shared/data", sections = "time,effects,auto,accuracy,lens,png";
  std::string lens_size = "512x256";
  int lens_threads = 2;
  int frames = 6, repeats = 3;
  bool quick = false;
  bool shared_given = false;  // --shared-data named: a folder without the frames is an error, not the demo
};

int run_render_bench(RenderBenchOptions o);

// PNG compression settings against each other: one frame as the renderer writes it, 8-bit RGB,
// through write_image_atomic (libpng); best of `repeats` encodes to a file; the decoded pixels
// are compared with the input.
void png_table(const Input& input, int repeats, const fs::path& tmp) {
  const cv::Mat image = read_image_native(input.png);
  if (image.depth() != CV_8U || image.channels() != 3) {
    std::cout << "\n(png table: the input is not 8-bit RGB; skipped)\n";
    return;
  }
  struct Setting { int level; const char* name; };
  const Setting settings[] = {{6, "level 6, adaptive filters (OpenImageIO's default)"},
                              {3, "level 3, adaptive filters (the default until run-length)"},
                              {1, "level 1, adaptive filters"},
                              {kPngRunLength, "run-length, Paeth filter (--png-level rle)"},
                              {kPngFast, "libdeflate level 1, Paeth filter (the default, --png-level fast)"}};
  std::cout << "\n### PNG encoding (" << image.cols << "x" << image.rows << " RGB, best of " << repeats
            << ")\n\n| setting | encode ms | vs level 3 | bytes | vs level 6 | pixels |\n|---|---|---|---|---|---|\n";
  const fs::path file = tmp / "png-bench.png";
  double ms3 = 0;
  std::uintmax_t bytes6 = 0;
  for (const Setting& s : settings) {
    double best = 1e30;
    for (int r = 0; r < repeats; ++r) {
      const double t0 = bench::now_ms();
      write_image_atomic(image, file, s.level);
      best = std::min(best, bench::now_ms() - t0);
    }
    const std::uintmax_t bytes = fs::file_size(file);
    if (s.level == 6) bytes6 = bytes;
    if (s.level == 3) ms3 = best;
    const cv::Mat back = read_image_native(file);
    const bool same = back.size() == image.size() && back.type() == image.type() && cv::norm(back, image, cv::NORM_INF) == 0;
    std::printf("| %s | %.1f | %s | %ju | %.2fx | %s |\n", s.name, best,
                ms3 > 0 && s.level != 3 ? (std::to_string(ms3 / best).substr(0, 4) + "x faster").c_str() : "-", bytes,
                bytes6 ? static_cast<double>(bytes) / bytes6 : 1.0, same ? "identical" : "DIFFERENT");
    std::fflush(stdout);
  }
}

}  // namespace

std::function<int()> add_render_bench(CLI::App& parent) {
  auto o = std::make_shared<RenderBenchOptions>();
  CLI::App* app = parent.add_subcommand("render", "Renderer: time per frame against the I/O floor, what each effect "
                                                  "costs, accuracy against time of the quality knobs");
  app->add_option("--input", o->input_path, "Background image (default: the first Cityscapes-mini frame, else the demo street)");
  app->add_option("--shared-data", o->shared, "Where ../shared/data is")->capture_default_str();
  app->add_option("--frames", o->frames, "Frames (different drops) per measurement")->capture_default_str()->check(CLI::Range(1, 100));
  app->add_option("--repeats", o->repeats, "Repetitions; medians are reported")->capture_default_str()->check(CLI::Range(1, 100));
  app->add_option("--sections", o->sections, "Comma-separated: time, effects, auto, accuracy, lens, png, core and camera (not in the default: the core's stages, fastest of the repeats per frame; the camera issue's speed targets at --lens-size without the 256-ray reference)")->capture_default_str();
  app->add_flag("--quick", o->quick, "Small and fast (a smoke run): 512x256 time table only, 1 frame");
  app->add_option("--lens-size", o->lens_size, "WIDTHxHEIGHT of the lens section's frame (2048x1024: the 256-ray "
                                               "reference alone takes minutes)")
      ->capture_default_str()->check(cli::width_height(16));
  app->add_option("--lens-threads", o->lens_threads, "Threads for the lens section")->capture_default_str()
      ->check(CLI::Range(1, 1024));
  return [o, app] {
    o->shared_given = app->count("--shared-data") > 0;
    if (cli::option_given_empty(*app, {"--input"})) {
      std::cerr << "raindrop-bench render: --input needs a value, got ''\n";
      return 2;
    }
    return run_render_bench(*o);
  };
}

namespace {

// The camera issue's speed targets alone, without the lens section's minutes-long 256-ray
// reference: each row's render core against the paper preset's on the same frame, the rows
// rendered in turn frame by frame (a change of the machine's load falls on all alike), the
// median over frames and repeats. Targets: the fast path within 2x the paper core, the
// 16-ray aperture reference within 10x.
void camera_table(const Input& input, int frames, int repeats, int threads, const cv::Size& size, const fs::path& tmp) {
  const Frame frame = make_frame(read_rgb8(input.png, false), input.calibration, size);
  struct Row {
    std::string preset, method, target;  // target: the issue's bound on "x paper", or "-"
    SceneConfig config;
    std::vector<SceneSample> scenes;
    std::vector<double> ms;
    int same_drops = -1;  // the row of the same drops through a pinhole, if any
  };
  std::vector<Row> rows;
  const SceneConfig paper = paper_with_70_drops();
  rows.push_back(
      {"paper (70 drops)", "pinhole + disk blur (the yardstick)", "-", paper, scenes_for(paper, frame.camera, frames), {}});
  // The issue's own camera, f/2 with the glass at 10 cm. First the yardstick's 70 paper drops,
  // the glass moved to 10 cm, through a pinhole with the disk blur and then, the same drops,
  // through a 5 mm lens focused on the street (no disk blur: the lens defocuses them); then
  // windshield-day's drops (the preset draws f/1.8-5.6 and 5-30 cm).
  SceneConfig paper_near = paper;
  paper_near.glass_distance_cm = {10, 10};
  const int near_row = static_cast<int>(rows.size());
  rows.push_back({"paper (70 drops), glass 10 cm", "pinhole + disk blur", "-", paper_near,
                  scenes_for(paper_near, frame.camera, frames), {}});
  const std::string paper_camera = kPaperAtIssueCamera;
  const std::string windshield_camera = "windshield-day at f/2, glass 10 cm";
  for (const std::string& preset : {std::string("lens-cover"), std::string("windshield-day"), paper_camera,
                                    windshield_camera, std::string("glass-droplets")}) {
    const SceneConfig fast = preset == paper_camera        ? at_issue_camera(paper)
                             : preset == windshield_camera ? at_issue_camera(scene_preset("windshield-day"))
                                                           : scene_preset(preset);
    std::vector<SceneSample> scenes;
    if (preset == paper_camera) {
      // The pinhole row's drops: its samples with the lens' (fixed) draws filled in.
      scenes = rows[near_row].scenes;
      for (SceneSample& s : scenes) {
        s.f_number = fast.lens.f_number.lo;
        s.focal_length_mm = fast.lens.focal_length_mm.lo;
      }
    } else {
      scenes = scenes_for(fast, frame.camera, frames);
    }
    const int same_drops = preset == paper_camera ? near_row : -1;
    // glass-droplets traces its street's defocus and its drops in focus: shown, not a target's row.
    const bool targeted = preset != "glass-droplets";
    rows.push_back({preset, "layered (fast path)", targeted ? "2x" : "-", fast, scenes, {}, same_drops});
    if (!targeted) continue;
    SceneConfig reference = fast;
    reference.lens.method = DefocusMethod::Aperture;
    reference.lens.aperture_samples = 16;
    rows.push_back({preset, "aperture, 16 rays", "10x", reference, scenes, {}, same_drops});
  }
  std::cerr << "bench render: camera targets\n";
  with_threads(threads, [&] {
    for (const Row& r : rows) render_frame(frame.clean, frame.camera, r.config, r.scenes[0]);  // warm-up
    for (int rep = 0; rep < repeats; ++rep) {
      for (int i = 0; i < frames; ++i) {
        for (Row& r : rows) r.ms.push_back(render_frame(frame.clean, frame.camera, r.config, r.scenes[i]).timings.core_ms());
      }
    }
  });
  const double paper_ms = median(rows[0].ms);
  std::cout << "\n### Camera targets (" << size.width << "x" << size.height << ", " << threads
            << (threads == 1 ? " thread, " : " threads, ") << frames << " frames per row, " << repeats
            << " repeats, rows in turn frame by frame; median render core)\n\n"
            << "Targets: the layered fast path within 2x the paper preset's core, the 16-ray aperture reference "
               "within 10x (glass-droplets traces its drops in focus and its street through the aperture: shown, "
               "not a target's row).\n\n"
            << "| preset | method | core ms | x paper | x the same drops through a pinhole | target |\n"
               "|---|---|---|---|---|---|\n";
  for (const Row& r : rows) {
    const double ms = median(r.ms);
    char same[32] = "-";
    if (r.same_drops >= 0) std::snprintf(same, sizeof same, "%.2f", ms / median(rows[static_cast<size_t>(r.same_drops)].ms));
    std::printf("| %s | %s | %.2f | %.2f | %s | %s |\n", r.preset.c_str(), r.method.c_str(), ms, ms / paper_ms, same,
                r.target.c_str());
  }
  std::fflush(stdout);

  // The issue's end-to-end target for the fast path: decode, render and the PNG files (with the
  // lens, the coverage too) within 1.3x the same loop with decode and encode only. The paper
  // preset beside it, as the time section measures it.
  std::cout << "\n### End to end against the I/O floor (" << size.width << "x" << size.height << ", " << threads
            << (threads == 1 ? " thread, " : " threads, ") << frames << " frames at a time, median of " << repeats
            << ")\n\nEach frame decoded from the input, rendered and written as raindrop-render writes it (rainy, "
               "clean, mask, and with a lens the 16-bit coverage; the clean image as the input file's bytes where "
               "the frame is that PNG as it was); the *I/O floor* is the same loop with decode and "
               "encode only, the same images.\n\n"
            << "| preset | method | end to end ms | I/O floor ms | end to end / floor | target |\n"
               "|---|---|---|---|---|---|\n";
  for (const Row& r : rows) {
    const bool fast = r.method == "layered (fast path)" && (r.preset == paper_camera || r.preset == windshield_camera);
    if (&r != &rows[0] && !fast) continue;
    std::cerr << "bench render: end to end, " << r.preset << "\n";
    const EndToEnd e = end_to_end(input, r.config, size, threads, frames, repeats, tmp);
    std::printf("| %s | %s | %.1f | %.1f | %.2f | %s |\n", r.preset.c_str(), r.method.c_str(), e.e2e, e.floor,
                e.e2e / e.floor, fast ? "1.3" : "-");
    std::fflush(stdout);
  }
}

int run_render_bench(RenderBenchOptions o) {
  std::string& input_path = o.input_path;
  std::string& shared = o.shared;
  std::string& sections = o.sections;
  int& frames = o.frames;
  int& repeats = o.repeats;
  const bool quick = o.quick;
  // Named sections, each checked: a misspelt one is an error, not a run that measures nothing.
  std::set<std::string> wanted;
  {
    const std::set<std::string> known{"time", "effects", "auto", "accuracy", "lens", "png", "core", "camera"};
    std::string names;
    for (const auto& k : known) names += (names.empty() ? "" : ", ") + k;
    // --quick runs the time table only, but the names given are still checked.
    std::stringstream list(sections);
    for (std::string name; std::getline(list, name, ',');) {
      if (name.empty()) continue;
      if (!known.count(name)) throw Error("--sections: unknown section '" + name + "' (" + names + ")");
      wanted.insert(name);
    }
    if (wanted.empty()) throw Error("--sections names no section (" + names + ")");
    if (quick) wanted = {"time"};
  }
  const fs::path tmp = bench::make_scratch_dir();
  // Removed however the run ends, an error included.
  struct RemoveOnExit {
    fs::path dir;
    ~RemoveOnExit() {
      std::error_code ec;
      fs::remove_all(dir, ec);
      bench::forget_scratch_dir(dir);
    }
  } remove_tmp{tmp};
  Input input;
  if (!input_path.empty()) {
    input.png = input_path;
    input.description = input_path;
    // Read once before the report starts: an unreadable input is refused in one line, not after
    // the header and half a table on stdout. The png section reads any image as stored (and
    // skips what is not 8-bit RGB); the others render it, as raindrop-render does without
    // --convert, whose advice is not this program's.
    if (wanted == std::set<std::string>{"png"}) {
      (void)read_image_native(input.png);
    } else {
      try {
        (void)read_rgb8(input.png, false);
      } catch (const Error& e) {
        std::string why = one_line(e.what());
        const auto advice = why.find(" (pass --convert");
        if (advice != std::string::npos)
          why = why.substr(0, advice) + " (the render sections take 8-bit RGB; --sections png takes any image)";
        throw Error("--input " + why);
      }
    }
  } else {
    try {
      const auto found = find_cityscapes(fs::path(shared) / "cityscapes-mini", "train");
      input.png = found.front().path;
      input.calibration = found.front().calibration;
      input.description = "Cityscapes " + found.front().id + " (2048x1024, calibrated)";
    } catch (const Error& e) {
      // A folder the user named that is there but unusable (a damaged camera file, a file for a
      // folder) is an error with its reason; one that is not there (a clone without the data
      // set, as the tests pass it) renders the demo, and says so on stderr too.
      std::error_code ec;
      if (o.shared_given && fs::exists(shared, ec))
        throw Error("--shared-data " + shared + ": " + one_line(e.what()));
      if (o.shared_given)
        std::cerr << "raindrop-bench render: warning: --shared-data " << shared << " is not there: the demo street is rendered\n";
      input.png = tmp / "street.png";
      write_image_atomic(demo_street(2048, 1024), input.png);
      input.description = "the demo street (2048x1024; " + shared + " not found)";
    }
  }
  std::vector<cv::Size> sizes{{2048, 1024}, {512, 256}};
  if (quick) {
    frames = 1;
    repeats = 1;
    sizes = {{512, 256}};
  }
  std::cout << "## raindrop-bench render\n\n"
            << "- machine: " << bench::machine_description() << "\n"
            << "- input: " << input.description << "\n"
            << "- scene: paper preset, 70 drops, exact caps, 1 spp, antialiased disk blur unless a row says otherwise\n"
            << "- " << frames << " frames per measurement, median of " << repeats << " repeats\n";
  if (wanted.count("time")) time_table(input, sizes, frames, repeats, tmp);
  if (wanted.count("core")) core_table(input, frames, repeats);
  if (wanted.count("png")) png_table(input, std::max(repeats, 3), tmp);
  if (wanted.count("effects")) effects_table(input, frames, repeats);
  if (wanted.count("auto")) auto_table(input, frames, repeats);
  if (wanted.count("accuracy")) accuracy_table(input, std::min(frames, 3), 1);
  if (wanted.count("lens")) lens_table(input, std::min(frames, 2), repeats, o.lens_threads, *cli::parse_width_height(o.lens_size));
  if (wanted.count("camera")) camera_table(input, frames, repeats, o.lens_threads, *cli::parse_width_height(o.lens_size), tmp);
  return 0;
}

}  // namespace
}  // namespace raindrop
