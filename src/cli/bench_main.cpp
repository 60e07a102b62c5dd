// raindrop-bench: prints the project's benchmark tables as markdown.
//   raindrop-bench render [options]   renderer: per-frame times vs the I/O floor, effects,
//                                     accuracy/time of the quality knobs
//   raindrop-bench remove [options]   raindrop-remove: per-stage times, GFLOP/s, trade-offs
#include <cstring>
#include <iostream>

#include "../bench/render_bench.h"
#ifdef RAINDROP_HAVE_REMOVE_BENCH
#include "../bench/remove_bench.h"
#endif
#include "raindrop/common/error.h"

int main(int argc, char** argv) {
  const char* usage =
      "usage: raindrop-bench render [--help] | raindrop-bench remove [--help]\n"
      "Prints benchmark tables (markdown) on stdout; progress on stderr.\n";
  if (argc < 2 || !std::strcmp(argv[1], "--help") || !std::strcmp(argv[1], "-h")) {
    std::cout << usage;
    return argc < 2 ? 2 : 0;
  }
  try {
    if (!std::strcmp(argv[1], "render")) return raindrop::render_bench(argc - 1, argv + 1);
#ifdef RAINDROP_HAVE_REMOVE_BENCH
    if (!std::strcmp(argv[1], "remove")) return raindrop::remove_bench(argc - 1, argv + 1);
#endif
  } catch (const std::exception& e) {
    std::cerr << "raindrop-bench: error: " << raindrop::one_line(e.what()) << "\n";
    return 1;
  }
  std::cerr << "raindrop-bench: unknown subcommand '" << argv[1] << "'\n" << usage;
  return 2;
}
