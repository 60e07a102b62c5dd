// raindrop-bench: prints the project's benchmark tables as markdown.
//   raindrop-bench render [options]   renderer: per-frame times vs the I/O floor, effects,
//                                     accuracy/time of the quality knobs
//   raindrop-bench remove [options]   raindrop-remove: per-stage times, GFLOP/s, trade-offs
#include <functional>
#include <iostream>

#include <CLI/CLI.hpp>

#ifdef RAINDROP_HAVE_RENDER_BENCH
#include "../bench/render_bench.h"
#include "raindrop/render/heap_tuning.h"
#endif
#ifdef RAINDROP_HAVE_REMOVE_BENCH
#include "../bench/remove_bench.h"
#include "raindrop/remove/session.h"
#endif
#include "raindrop/common/error.h"
#include "raindrop/common/version.h"

int main(int argc, char** argv) {
#ifdef RAINDROP_HAVE_REMOVE_BENCH
  // First, while this is the only thread (raindrop/remove/session.h says why).
  raindrop::removal::turn_off_onnxruntime_telemetry();
#endif
  CLI::App app{"raindrop-bench: benchmark tables (markdown on stdout, progress on stderr). Speed is measured here, "
               "never asserted in tests."};
  app.set_version_flag("--version", std::string("raindrop-bench ") + raindrop::kVersion);
  app.require_subcommand(1);
#ifdef RAINDROP_HAVE_RENDER_BENCH
  const std::function<int()> render = raindrop::add_render_bench(app);
#endif
#ifdef RAINDROP_HAVE_REMOVE_BENCH
  const std::function<int()> remove = raindrop::add_remove_bench(app);
#endif
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  try {
#ifdef RAINDROP_HAVE_RENDER_BENCH
    if (app.got_subcommand("render")) {
      raindrop::keep_freed_frame_memory();  // as raindrop-render runs (heap_tuning.h)
      return render();
    }
#endif
#ifdef RAINDROP_HAVE_REMOVE_BENCH
    if (app.got_subcommand("remove")) return remove();
#endif
  } catch (const std::exception& e) {
    std::cerr << "raindrop-bench: error: " << raindrop::one_line(e.what()) << "\n";
    return 1;
  }
  return 2;  // unreachable: CLI11 requires one subcommand
}
