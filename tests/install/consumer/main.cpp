// Links the installed refiner (and FCN selector) and checks that they work with defaults.
#include <lookup/refine/refiner.h>

#include <iostream>

#ifdef CONSUMER_WITH_FCN
#include <lookup/fcn/model.h>
#endif

int main() {
    lookup::refine::Refiner refiner;  // throws if the default options were invalid
    std::cout << "search_range_px=" << refiner.options().matcher.search_range_px << "\n";
    if (refiner.options().matcher.search_range_px <= 0) return 1;
#ifdef CONSUMER_WITH_FCN
    // A fresh network runs LibTorch: the package config must have found Torch.
    const lookup::fcn::HeatMapModel model(lookup::fcn::NetworkOptions{});
    std::cout << "fcn_parameters=" << model.parameterCount() << "\n";
    if (model.parameterCount() == 0) return 1;
#endif
    return 0;
}
