#pragma once
// One Remover on the untrained fixture models (tools/tests/fixtures/models-smoke), shared by the
// tests of one program: loading the graphs once keeps the suites fast.
#include "raindrop/remove/remover.h"
#include "remove_test_util.h"

namespace removetest {

inline raindrop::removal::Remover& smoke_remover() {
  static raindrop::removal::Remover r(smoke_models());
  return r;
}

}  // namespace removetest
