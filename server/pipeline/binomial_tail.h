// The binomial lower tail: how likely k or fewer successes are in n trials of rate p. A
// sensitivity claim checked on a few dozen pieces reads one or two short of its rate by
// chance about as often as not; this says when a shortfall is evidence against the claim.
#pragma once

namespace rangex {

// P(X <= k) for X ~ Binomial(n, p); 1 when k >= n, 0 when k < 0.
double binomial_at_most(int k, int n, double p);

}  // namespace rangex
