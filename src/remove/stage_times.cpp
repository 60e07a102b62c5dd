#include "raindrop/remove/stage_times.h"

#include <cstdio>

namespace raindrop::removal {

StageTimes& StageTimes::operator+=(const StageTimes& o) {
  convert += o.convert, edge += o.edge, rdn += o.rdn, mask += o.mask;
  rrn += o.rrn, blend += o.blend, rfn += o.rfn, output += o.output, router += o.router;
  return *this;
}

StageTimes& StageTimes::operator/=(double n) {
  convert /= n, edge /= n, rdn /= n, mask /= n, rrn /= n, blend /= n, rfn /= n, output /= n, router /= n;
  return *this;
}

std::string StageTimes::describe() const {
  char buf[320], routed[48] = "";
  if (router > 0) std::snprintf(routed, sizeof routed, ", router %.1f", router);
  std::snprintf(buf, sizeof buf,
                "convert %.1f, edge %.1f, RDN %.1f, threshold+dilation %.1f, 3RN %.1f, blend %.1f, RFN %.1f, "
                "output %.1f%s ms; stages summed %.1f ms",
                convert, edge, rdn, mask, rrn, blend, rfn, output, routed, total());
  return buf;
}

}  // namespace raindrop::removal
