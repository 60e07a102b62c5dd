#pragma once
// raindrop-bench remove: raindrop-remove's time per image and per stage, and the GFLOP/s the
// three networks reach (markdown tables on stdout, progress on stderr).
namespace raindrop {
int remove_bench(int argc, char** argv);
}
