// lookup-eval: accuracy of localisation runs against ground truth, per traverse and method
// (lookup/eval/eval_app.h).
#include "lookup/common/app.h"
#include "lookup/eval/eval_app.h"

int main(int argc, char** argv) {
    lookup::eval::EvalApp app;
    return lookup::common::runApp("lookup-eval", app, argc, argv);
}
