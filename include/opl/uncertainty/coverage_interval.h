// Coverage intervals from a Monte Carlo sample, as JCGM 101:2008 (GUM
// Supplement 1), clause 7.7, specifies them.
//
// Sort the M values: y_(1) <= ... <= y_(M) (1-based). For a coverage
// probability p let
//     q = p M            when p M is an integer,
//     q = floor(p M + 1/2) otherwise.
// Then [y_(r), y_(r+q)] is a 100p % coverage interval for any r = 1 .. M - q.
//  - Probabilistically symmetric (7.7.1): r = (M - q) / 2 when that is an
//    integer, else the integer part of (M - q + 1) / 2. Its ends estimate the
//    (1 - p)/2 and (1 + p)/2 quantiles.
//  - Shortest (7.7.2): the r that minimises y_(r+q) - y_(r) (the first such r
//    on ties).
// Both need M - q >= 1 (about M >= 1 / (1 - p): 20 values for p = 0.95);
// JCGM 101 7.2.2 asks for M large compared with 1 / (1 - p) (e.g. 10^4 times
// larger) for a reliable interval (docs/uncertainty.md).
#pragma once

#include <vector>

#include "opl/core/status.h"

namespace opl {

enum class CoverageIntervalKind {
  kProbabilisticallySymmetric,  // JCGM 101 7.7.1
  kShortest,                    // JCGM 101 7.7.2
};

struct CoverageInterval {
  double low = 0.0;
  double high = 0.0;
  // The 1-based order statistics chosen: low = y_(r), high = y_(r + q).
  int r = 0;
  int q = 0;
};

// The index q of JCGM 101 7.7 for M values and probability p (see above).
int CoverageIndexQ(int num_values, double probability);

// The 100p % coverage interval of `values` (any order; copied and sorted).
// InvalidArgument when p is not in (0, 1), a value is not finite, or the
// sample is too small (M - q < 1), with the numbers in the message.
Result<CoverageInterval> ComputeCoverageInterval(const std::vector<double>& values,
                                                 double probability,
                                                 CoverageIntervalKind kind);

// The same on values already sorted ascending (not checked).
Result<CoverageInterval> CoverageIntervalOfSorted(const std::vector<double>& sorted,
                                                  double probability,
                                                  CoverageIntervalKind kind);

}  // namespace opl
