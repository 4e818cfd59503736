// grid_channels_of_body(): --check's list of the channel sets a body sums into (grid_channels.h).
#include "engine/grid_channels.h"

namespace fbar {

std::string grid_channels_of_body(GridFeatures body, GridFeatures scene) {
  std::string out;
  for (const GridSetDecl& d : kGridSets) {
    if (!d.p2g || !scene.has(d.need)) continue;
    const bool own = body.has(d.need);
    if (!own && !d.every_body) continue;
    if (!out.empty()) out += " + ";
    out += d.name;
    out += " (" + std::to_string(d.channels);
    if (!own) out += ": every body sums it when one needs it";
    out += ")";
  }
  return out;
}

}  // namespace fbar
