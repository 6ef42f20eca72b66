#include "opl/model/spot.h"

namespace opl {

std::map<std::string, std::vector<SpotObservation>> GroupSpotsBySource(
    const std::vector<Spot>& spots) {
  std::map<std::string, std::vector<SpotObservation>> groups;
  for (const Spot& s : spots) {
    if (s.assigned()) groups[s.source].push_back(s.observation);
  }
  return groups;
}

}  // namespace opl
