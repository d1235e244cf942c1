// Links the installed refiner and checks that its default options are valid.
#include <lookup/refine/refiner.h>

#include <iostream>

int main() {
    lookup::refine::Refiner refiner;  // throws if the default options were invalid
    std::cout << "search_range_px=" << refiner.options().matcher.search_range_px << "\n";
    return refiner.options().matcher.search_range_px > 0 ? 0 : 1;
}
