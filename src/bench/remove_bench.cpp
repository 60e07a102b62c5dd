// raindrop-bench remove: how long raindrop-remove takes per image, stage by stage, at the
// paper's 256x512 and at Cityscapes' 1024x2048, with 1 and 2 threads (docs/DESIGN.md
// section 6: mean of 20 runs after warm-up, threads and hardware stated), and the GFLOP/s
// the networks reach. GFLOPs come from the model folder's export.json (measured by the
// exporter at 256x512) scaled by the pixels the networks actually ran on (padded tiles,
// overlaps included).
#include "remove_bench.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <unistd.h>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "../cli/options.h"
#include "bench_util.h"
#include "raindrop/common/error.h"
#include "raindrop/common/image_io.h"
#include "raindrop/remove/int8_precision.h"
#include "raindrop/remove/model_paths.h"
#include "raindrop/remove/remover.h"
#include "raindrop/common/demo.h"

namespace raindrop {
namespace fs = std::filesystem;
using namespace removal;

namespace {

struct Gflops {
  double rdn = 0, rrn = 0, rfn = 0;  // at 256x512
};

std::optional<Gflops> read_gflops(const fs::path& dir) {
  std::ifstream in(dir / "export.json");
  if (!in) return std::nullopt;
  try {
    const auto j = nlohmann::json::parse(in);
    const auto& g = j.at("gflops_256x512");
    const Gflops f{g.at("rdn").get<double>(), g.at("rrn").get<double>(), g.at("rfn").get<double>()};
    // A damaged or hand-edited file's numbers would print as GFLOP/s rows that mean nothing: each
    // network costs something, and far less than a teraflop per 256x512 image (the paper's whole
    // pipeline is 146 GFLOPs there).
    for (const double v : {f.rdn, f.rrn, f.rfn})
      if (!std::isfinite(v) || v <= 0 || v > 1000) return std::nullopt;
    return f;
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

struct Row {
  std::string models, size;
  int threads = 0, tiles = 0, runs = 0;
  double scale = 1;
  StageTimes mean;
  double wall_mean = 0, wall_median = 0;
  double first = 0;  // the first Remover::run on this size (ONNX Runtime's first run on a new shape)
  std::optional<Gflops> gflop;  // for this image (scaled)
};

std::string fmt(double v, const char* f = "%.1f") {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

// The raindrop-remove command line for `input` (paths quoted for the shell).
std::string remove_command(const fs::path& program, const fs::path& model_dir, const fs::path& input,
                           const fs::path& output, int threads, const std::string& extra = "") {
  const auto q = [](const fs::path& p) {
    std::string out = "'";
    for (const char c : p.string()) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return out + "'";
  };
  return q(program) + " " + q(input) + " " + q(output) + " --models " + q(model_dir) + " -j " + std::to_string(threads) +
         (extra.empty() ? "" : " " + extra);
}

// One raindrop-remove process on `input`, from fork to exit, in ms; -1 if it failed.
double time_process(const fs::path& program, const fs::path& model_dir, const fs::path& input, const fs::path& output,
                    int threads, const std::string& extra = "") {
  const std::string cmd = remove_command(program, model_dir, input, output, threads, extra) + " -q";
  const double t0 = bench::now_ms();
  const int rc = std::system(cmd.c_str());
  const double ms = bench::now_ms() - t0;
  return rc == 0 ? ms : -1;
}

struct RemoveBenchOptions {
  std::vector<std::string> model_dirs;
  std::vector<int> thread_counts{1, 2};
  GraphOpt graph_opt = GraphOpt::all;
  int tile = kDefaultTile, overlap = kDefaultOverlap, runs = 0;
  bool quick = false;
  std::vector<std::string> size_texts{"512x256", "2048x1024"};
  std::optional<double> scale;
  std::vector<std::string> process_sizes{"1280x720"};
  std::vector<std::string> process_images;  // photographs for the process table, routed and not
};

int run_remove_bench(RemoveBenchOptions o);

}  // namespace

std::function<int()> add_remove_bench(CLI::App& parent) {
  auto o = std::make_shared<RemoveBenchOptions>();
  CLI::App* app = parent.add_subcommand("remove", "raindrop-remove: time per image and stage, GFLOP/s, process start "
                                                  "to file written");
  app->add_option("--models", o->model_dirs, "Model folder (repeatable: one set of rows per folder; default: the one "
                                             "raindrop-remove finds)");
  app->add_option("--threads", o->thread_counts, "Thread counts to measure (repeatable)")->capture_default_str()
      ->check(CLI::Range(1, 1024));
  app->add_option("--graph-opt", o->graph_opt, "ONNX Runtime graph optimisation level")
      ->transform(cli::names_to(graph_opt_names()))->default_str("all");
  app->add_option("--tile", o->tile, "Tile size (0: never tile)")->capture_default_str();
  app->add_option("--tile-overlap", o->overlap, "Tile overlap")->capture_default_str();
  app->add_option("--runs", o->runs, "Timed runs per row (default 20; 3 with --quick)")->check(CLI::Range(1, 1000));
  app->add_flag("--quick", o->quick, "3 timed runs after 1 warm-up instead of 20 after 2");
  app->add_option("--size", o->size_texts, "Image sizes WIDTHxHEIGHT (repeatable)")->capture_default_str()
      ->check(cli::width_height());
  app->add_option("--scale", o->scale, "Working scale (default: raindrop-remove's, the long side brought to 512; 1: full size)")
      ->check(CLI::Range(0.0, 1.0));
  // Checked by the parser, before the (minutes of) rows above it in the output are measured.
  app->add_option("--process-size", o->process_sizes,
                  "WIDTHxHEIGHT of the image for the process-start-to-file rows (raindrop-remove run as a program; "
                  "repeatable: one row per size and model folder; the first also for the coarse-pass and "
                  "--mirror-average tables; empty: none)")
      ->capture_default_str()->check(cli::width_height(1, 16384, /*allow_empty=*/true));
  app->add_option("--process-image", o->process_images,
                  "A photograph (any format raindrop-remove reads) for a process-start-to-file table of its own, with "
                  "the models' detector router and without it (--no-router) in alternate runs, naming the detector the "
                  "router chose (repeatable)")
      ->check(CLI::ExistingFile);
  return [o, app] {
    // An empty value read as 0 ("--tile ''": never tile) instead of an error.
    if (const auto name = cli::option_given_empty(*app, {"--tile", "--tile-overlap"})) {
      std::cerr << "raindrop-bench remove: " << *name << " needs a value, got ''\n";
      return 2;
    }
    return run_remove_bench(*o);
  };
}

namespace {

// What an option of Remover::run costs, measured on the street image with it on and off in
// alternate runs (so load changes hit both alike): as found, and with a threshold below 0,
// which makes the whole frame one drop (a large one, for the coarse pass), so that every
// network of both passes runs. `set(options, on)` turns the option on or off.
void print_option_cost(const std::vector<std::string>& model_dirs, cv::Size size, SessionConfig session, int runs,
                       int warmup, const std::string& title, const std::string& what, const std::string& off_name,
                       const std::string& on_name, const std::function<void(RemoveOptions&, bool)>& set) {
  const int threads = session.threads;
  std::cout << "\n## raindrop-remove: " << title << "\n\n"
            << size.width << "x" << size.height << " street image (the first --process-size), " << threads << " thread" << (threads == 1 ? "" : "s")
            << ", default working scale; Remover::run " << what << " in alternate runs, median of " << runs
            << " each after " << warmup << " warm-up pair" << (warmup == 1 ? "" : "s")
            << ". \"all one drop\": threshold -1, every pixel a drop, so every network of both passes runs.\n\n"
               "| models | mask | " << off_name << " (ms) | " << on_name << " (ms) | " << on_name << " / " << off_name
            << " | pixels through the networks, " << on_name << " / " << off_name << " | large drops |\n"
               "|---|---|---|---|---|---|---|\n";
  const cv::Mat image = demo_street(size.width, size.height);
  for (const auto& dir : model_dirs) {
    Remover remover(dir, session);
    for (const bool all_one_drop : {false, true}) {
      RemoveOptions on, off;
      if (all_one_drop) {
        on.threshold = off.threshold = -1.0;
        // Every network of both passes: no region is too sharp for the coarse pass (large_drops.h).
        on.large_drop_max_sharpness = off.large_drop_max_sharpness = std::numeric_limits<double>::infinity();
      }
      set(on, true);
      set(off, false);
      std::vector<double> t_on, t_off;
      RemoveResult r_on, r_off;
      for (int i = 0; i < warmup + runs; ++i) {
        double t0 = bench::now_ms();
        r_off = remover.run(image, off);
        const double w_off = bench::now_ms() - t0;
        t0 = bench::now_ms();
        r_on = remover.run(image, on);
        const double w_on = bench::now_ms() - t0;
        if (i < warmup) continue;
        t_off.push_back(w_off);
        t_on.push_back(w_on);
      }
      const double a = bench::median(t_off), b = bench::median(t_on);
      const std::string large = remover.large_drop_model_dir().empty()
                                    ? std::string()
                                    : " (large drops: " + remover.large_drop_model_dir().filename().string() + ")";
      std::cout << "| " << fs::path(dir).filename().string() << large << " | " << (all_one_drop ? "all one drop" : "as found")
                << " | " << fmt(a) << " | " << fmt(b) << " | " << fmt(b / a, "%.2f") << " | "
                << fmt((r_on.network_pixels + r_on.reconstructed_pixels) /
                           (r_off.network_pixels + r_off.reconstructed_pixels),
                       "%.2f")
                << " | " << r_on.large_drops << " |\n";
    }
  }
}

// The detector raindrop-remove's router chose for `input` (from its --time line): "routed to
// NAME", "kept", "no router" (the models have none), or "failed".
std::string router_choice(const fs::path& program, const fs::path& model_dir, const fs::path& input, const fs::path& output,
                          int threads) {
  FILE* pipe = popen((remove_command(program, model_dir, input, output, threads, "--time") + " 2>&1").c_str(), "r");
  if (!pipe) return "failed";
  std::string text;
  char buf[4096];
  while (std::fgets(buf, sizeof buf, pipe)) text += buf;
  if (pclose(pipe) != 0) return "failed";
  const auto at = text.find(", detector ");
  if (at == std::string::npos) return "no router";
  if (text.compare(at, 26, ", detector the models' own") == 0) return "kept";
  const auto name = text.find('\'', at), end = text.find('\'', name + 1);
  return "routed to " + text.substr(name + 1, end - name - 1);
}

// Process start to file written on the user's photographs, with the router and without it
// (--no-router), the two alternated run by run so that load changes hit both alike.
// Returns false when a run failed (its row says so).
bool print_photograph_times(const std::vector<std::string>& model_dirs, const std::vector<std::string>& images,
                            int threads, int runs) {
  bool all_ran = true;
  std::error_code ec;
  const fs::path program = fs::read_symlink("/proc/self/exe", ec).parent_path() / "raindrop-remove";
  const fs::path tmp = bench::make_scratch_dir();
  std::cout << "\n## raindrop-remove: process start to file written, photographs\n\n"
            << "`raindrop-remove PHOTO out.png --models DIR -j " << threads << "` (each --process-image), with the "
            << "detector router and with --no-router in alternate runs; \"first\": each's first process, \"warm\": median "
            << "of the next " << runs << ". \"router\": what the router chose (docs/RESULTS.md 4.34).\n\n"
            << "| models | photograph | size (WxH) | router | first (ms) | warm median (ms) | --no-router first (ms) | "
               "--no-router warm median (ms) | routed / --no-router |\n|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& image : images) {
    std::string size = "?";
    try {
      const ImageHeader header = read_header(image);
      size = std::to_string(header.width) + "x" + std::to_string(header.height);
    } catch (const Error&) {
      // raindrop-remove's own run below says what is wrong with the file
    }
    for (const auto& dir : model_dirs) {
      const fs::path out = tmp / "out.png";
      const std::string choice = router_choice(program, dir, image, out, threads);
      std::vector<double> on, off;
      for (int i = 0; i <= runs && choice != "failed"; ++i) {
        on.push_back(time_process(program, dir, image, out, threads));
        off.push_back(time_process(program, dir, image, out, threads, "--no-router"));
        if (on.back() < 0 || off.back() < 0) break;  // one failure says it: no more runs of it
      }
      const auto failed = [](const std::vector<double>& v) { return std::any_of(v.begin(), v.end(), [](double t) { return t < 0; }); };
      std::cout << "| " << fs::path(dir).filename().string() << " | " << fs::path(image).filename().string() << " | " << size
                << " | " << choice << " | ";
      if (choice == "failed" || failed(on) || failed(off)) {
        std::cout << "failed (" << program.string() << ") | | | | |\n";
        all_ran = false;
        continue;
      }
      const double on_warm = bench::median(std::vector<double>(on.begin() + 1, on.end()));
      const double off_warm = bench::median(std::vector<double>(off.begin() + 1, off.end()));
      std::cout << fmt(on.front()) << " | " << fmt(on_warm) << " | " << fmt(off.front()) << " | " << fmt(off_warm) << " | "
                << fmt(on_warm / off_warm, "%.2f") << " |\n";
    }
  }
  fs::remove_all(tmp, ec);
  bench::forget_scratch_dir(tmp);
  return all_ran;
}

int run_remove_bench(RemoveBenchOptions o) {
  try {
    check_tile_options(o.tile, o.overlap);
  } catch (const Error& e) {
    std::cerr << "raindrop-bench remove: " << one_line(e.what()) << "\n";
    return 2;
  }
  // Each photograph read now, before minutes of measuring: a damaged one was found only by its
  // table's runs, which said "failed" and exited 0.
  for (const auto& image : o.process_images) {
    try {
      read_image_native(image);
    } catch (const Error& e) {
      std::cerr << "raindrop-bench remove: error: --process-image " << one_line(e.what()) << "\n";
      return 1;
    }
  }
  auto& model_dirs = o.model_dirs;
  const auto& thread_counts = o.thread_counts;
  int& runs = o.runs;
  const bool quick = o.quick;
  const auto& scale = o.scale;

  if (runs == 0) runs = quick ? 3 : 20;
  const int warmup = quick ? 1 : 2;
  if (model_dirs.empty()) model_dirs.push_back(find_models(default_model_search()).string());

  std::vector<cv::Size> sizes;
  for (const auto& text : o.size_texts) sizes.push_back(*cli::parse_width_height(text));  // checked by the parser
  std::vector<cv::Size> process_sizes;  // checked by the parser; "" (none) left out
  for (const auto& text : o.process_sizes) {
    if (!text.empty()) process_sizes.push_back(*cli::parse_width_height(text));
  }
  const std::optional<cv::Size> process =
      process_sizes.empty() ? std::nullopt : std::optional<cv::Size>(process_sizes.front());
  SessionConfig session;
  session.graph_opt = o.graph_opt;
  RemoveOptions options;
  options.tile = o.tile;
  options.overlap = o.overlap;
  options.scale = scale;
  // The working-scale pass alone, as the Python reference that scores accuracy runs it
  // (tradeoffs.py pairs the two); the coarse pass for large drops is measured in RESULTS 4.6.
  options.large_drops = false;
  if (scale && !(*scale > 0)) {
    std::cerr << "raindrop-bench remove: --scale must be in (0, 1]\n";
    return 2;
  }

  std::vector<Row> rows;
  std::vector<std::pair<std::string, double>> load_ms;  // session creation per model folder and threads
  for (const auto& dir : model_dirs) {
    const auto gflops = read_gflops(dir);
    for (const int threads : thread_counts) {
      session.threads = threads;
      const double load_t0 = bench::now_ms();
      Remover remover(dir, session);
      load_ms.push_back({fs::path(dir).filename().string() + ", " + std::to_string(threads) + " thread" +
                             (threads == 1 ? "" : "s"),
                         bench::now_ms() - load_t0});
      const std::string name = remover.info().config + " (" + fs::path(dir).filename().string() + ")";
      for (const auto& size : sizes) {
        const cv::Mat image = demo_street(size.width, size.height);
        Row row;
        row.models = name;
        row.size = std::to_string(size.width) + "x" + std::to_string(size.height);
        row.threads = threads;
        row.runs = runs;
        std::fprintf(stderr, "bench remove: %s %s, %d thread%s: ", name.c_str(), row.size.c_str(), threads,
                     threads == 1 ? "" : "s");
        double pixels = 0;
        std::vector<double> walls;
        for (int i = 0; i < warmup + runs; ++i) {
          const double t0 = bench::now_ms();
          const RemoveResult r = remover.run(image, options);
          const double wall = bench::now_ms() - t0;
          if (i == 0) row.first = wall;
          row.scale = r.scale;
          if (i < warmup) continue;
          row.mean += r.times;
          walls.push_back(wall);
          row.tiles = r.tiles_x * r.tiles_y;
          pixels = r.network_pixels;
          std::fputc('.', stderr);
        }
        std::fputc('\n', stderr);
        row.mean /= runs;
        row.wall_mean = bench::mean(walls);
        row.wall_median = bench::median(walls);
        if (gflops) {
          const double ratio = pixels / (256.0 * 512.0);
          row.gflop = Gflops{gflops->rdn * ratio, gflops->rrn * ratio, gflops->rfn * ratio};
        }
        rows.push_back(row);
      }
    }
  }

  std::cout << "## raindrop-remove: time per image\n\n"
            << "Machine: " << bench::machine_description() << "; " << ort_description() << ", CPU (int8 models: "
            << int8_kernels_description() << "), graph optimisation "
            << to_string(o.graph_opt) << "; tile " << (o.tile ? std::to_string(o.tile) : std::string("off")) << " (overlap " << o.overlap
            << "). Mean of " << runs << " runs after " << warmup << " warm-up run" << (warmup == 1 ? "" : "s")
            << ", in ms; input: the built-in street image (8-bit RGB). \"other\": input conversion, tile blending, "
               "quantisation and the detector router's features (where the models have one); \"total\": wall time of Remover::run. The working-scale pass alone (raindrop-remove "
               "--no-large-drops); what the coarse pass for large drops adds: its own table below.\n\n";
  std::cout << "| models | size (WxH) | scale | threads | tiles | edge | RDN | threshold+dilation | 3RN | blend | RFN | "
               "other | total | median total | first run |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& r : rows) {
    std::cout << "| " << r.models << " | " << r.size << " | " << fmt(r.scale, "%.3g") << " | " << r.threads << " | "
              << r.tiles << " | " << fmt(r.mean.edge)
              << " | " << fmt(r.mean.rdn) << " | " << fmt(r.mean.mask) << " | " << fmt(r.mean.rrn) << " | "
              << fmt(r.mean.blend) << " | " << fmt(r.mean.rfn) << " | " << fmt(r.mean.convert + r.mean.output + r.mean.router) << " | "
              << fmt(r.wall_mean) << " | " << fmt(r.wall_median) << " | " << fmt(r.first) << " |\n";
  }
  std::cout << "\n\"first run\": the first Remover::run on that size with a fresh session (not in the mean): ONNX "
               "Runtime's first run on a new input shape is slower (not because of its memory planning: "
               "docs/RESULTS.md 3.5). Session creation (loading and "
               "optimising the three graphs), ms:";
  for (const auto& [what, ms] : load_ms) std::cout << " " << what << " " << fmt(ms) << ";";
  std::cout << "\n";
  if (!process_sizes.empty()) {
    std::error_code ec;
    const fs::path program = fs::read_symlink("/proc/self/exe", ec).parent_path() / "raindrop-remove";
    const fs::path tmp = bench::make_scratch_dir();
    const int threads = thread_counts.back();
    std::cout << "\n## raindrop-remove: process start to file written\n\n"
              << "`raindrop-remove in.png out.png --models DIR -j " << threads << "` on the built-in street image "
              << "(PNG, each --process-size), run as a program: process start, model loading, decoding, removal at the "
                 "default working scale, encoding, exit. \"first\": the first process of the bench for that model "
                 "folder and size (files possibly not yet in the page cache); \"warm\": median of the next "
              << runs << ".\n\n| models | size (WxH) | first (ms) | warm median (ms) | warm min (ms) |\n|---|---|---|---|---|\n";
    for (const cv::Size& size : process_sizes) {
      write_image_atomic(demo_street(size.width, size.height), tmp / "in.png");
      for (const auto& dir : model_dirs) {
        std::vector<double> warm;
        const double first = time_process(program, dir, tmp / "in.png", tmp / "out.png", threads);
        for (int i = 0; i < runs; ++i) warm.push_back(time_process(program, dir, tmp / "in.png", tmp / "out.png", threads));
        const bool ok = first >= 0 && std::all_of(warm.begin(), warm.end(), [](double v) { return v >= 0; });
        std::cout << "| " << fs::path(dir).filename().string() << " | " << size.width << "x" << size.height << " | "
                  << (ok ? fmt(first) + " | " + fmt(bench::median(warm)) + " | " +
                               fmt(*std::min_element(warm.begin(), warm.end())) + " |"
                         : std::string("failed (") + program.string() + ") | | |")
                  << "\n";
      }
    }
    fs::remove_all(tmp, ec);
    bench::forget_scratch_dir(tmp);
  }
  if (!o.process_images.empty() && !print_photograph_times(model_dirs, o.process_images, thread_counts.back(), runs)) {
    std::cerr << "raindrop-bench remove: error: a photograph's run failed (its row says so)\n";
    return 1;
  }
  if (process) {  // the first --process-size image, the last --threads value, the same graph optimisation
    session.threads = thread_counts.back();
    // The coarse pass for large drops (large_drops.h): off is --no-large-drops.
    print_option_cost(model_dirs, *process, session, runs, warmup, "what the coarse pass for large drops costs",
                      "with the coarse pass and without it (--no-large-drops)", "without", "with",
                      [](RemoveOptions& opts, bool on) { opts.large_drops = on; });
    // --mirror-average: the working-scale pass's 3RN and RFN also averaged with the mirror image's.
    print_option_cost(model_dirs, *process, session, runs, warmup, "what --mirror-average costs",
                      "with the working-scale pass's 3RN and RFN averaged with their run on the mirror image "
                      "(--mirror-average) and without", "without", "with", [](RemoveOptions& opts, bool on) { opts.mirror_average = on; });
    // --fine-drops: the deciding detector again at 1.5 times the working scale (fine_drops.h).
    print_option_cost(model_dirs, *process, session, runs, warmup, "what --fine-drops costs",
                      "with the fine pass for small drops (--fine-drops: the detector at 1.5 times the working scale, "
                      "small parts over smooth surroundings filled) and without", "without", "with",
                      [](RemoveOptions& opts, bool on) { opts.fine_drops = on; });
  }
  std::cout << "\n## raindrop-remove: GFLOP/s\n\nGFLOPs from each model folder's export.json (at 256x512), scaled by "
               "the pixels the networks ran on (tiles and their overlaps included).\n\n"
               "| models | size (WxH) | threads | GFLOP | RDN GFLOP/s | 3RN GFLOP/s | RFN GFLOP/s | overall GFLOP/s |\n"
               "|---|---|---|---|---|---|---|---|\n";
  for (const auto& r : rows) {
    std::cout << "| " << r.models << " | " << r.size << " | " << r.threads << " | ";
    if (!r.gflop) {
      std::cout << "n/a (no usable export.json) | | | | |\n";
      continue;
    }
    const auto& g = *r.gflop;
    const double total = g.rdn + g.rrn + g.rfn;
    const auto rate = [](double gf, double ms) { return ms > 0 ? fmt(gf / (ms / 1000.0)) : std::string("n/a"); };
    std::cout << fmt(total, "%.2f") << " | " << rate(g.rdn, r.mean.rdn) << " | " << rate(g.rrn, r.mean.rrn) << " | "
              << rate(g.rfn, r.mean.rfn) << " | " << rate(total, r.wall_mean) << " |\n";
  }
  return 0;
}

}  // namespace
}  // namespace raindrop
