// Counting heap allocations in the runtime's test program: no_allocation_test.cc interposes
// malloc and its family for the whole program and counts calls between these two (each
// program's other tests run with the count off).
#pragma once

namespace rodfit_test {

/// Zeroes the count and starts counting malloc, calloc, realloc and the aligned allocators
/// (operator new and Eigen's dynamic matrices allocate through them).
void StartCountingAllocations();
/// Stops counting; the allocations since the start.
long StopCountingAllocations();

}  // namespace rodfit_test
