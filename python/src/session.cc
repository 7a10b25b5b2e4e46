#include "session.h"

#include <pybind11/numpy.h>

#include <array>
#include <atomic>
#include <optional>
#include <vector>

#include "arrays.h"
#include "errors.h"
#include "model.h"
#include "sfrt/isa.h"
#include "sfrt/pipeline/window_input.h"
#include "sfrt/session.h"

namespace py = pybind11;

namespace sfrt::python {
namespace {

camera::ColorOrder ParseColor(const std::string& color) {
  if (color == "bgr") return camera::ColorOrder::kBGR;
  if (color == "rgb") return camera::ColorOrder::kRGB;
  throw py::value_error(
      "color: expected 'bgr' (as OpenCV decodes images) or 'rgb' (as PIL and "
      "imageio do), got '" +
      color + "'");
}

class PySession {
 public:
  PySession(std::shared_ptr<PyModel> model, const py::object& size, int threads,
            const std::string& isa, bool allow_aspect_change)
      : model_(std::move(model)), allow_aspect_change_(allow_aspect_change) {
    SessionSize(*model_, size, &height_, &width_);
    SessionOptions options;
    options.max_height = height_;
    options.max_width = width_;
    options.threads = ThreadsArgument(threads);
    options.isa = ParseIsaArgument(isa);
    Result<std::unique_ptr<Session>> session = [&] {
      py::gil_scoped_release released;
      return Session::Create(model_->model, options);
    }();
    if (!session.ok()) {
      throw Error("cannot create a session for " + std::to_string(height_) + "x" +
                  std::to_string(width_) + ": " + session.message());
    }
    session_ = std::move(session).value();
    Result<TensorShape> out = session_->OutputShape(height_, width_);
    ThrowIfError(out.status());
    output_shape_ = *out;
  }

  py::array_t<float> Run(const py::object& l0, const py::object& r0, const py::object& l1,
                         const py::object& r1, const std::string& color, const py::object& out) {
    return RunWindow({l0, r0, l1, r1}, {"left0", "right0", "left1", "right1"}, false, color,
                     1000.0f, out);
  }

  py::array_t<float> RunRgbd(const py::object& c0, const py::object& d0, const py::object& c1,
                             const py::object& d1, float depth_units, const std::string& color,
                             const py::object& out) {
    return RunWindow({c0, d0, c1, d1}, {"color0", "depth0", "color1", "depth1"}, true, color,
                     depth_units, out);
  }

  py::array_t<float> RunTensor(const py::object& x, const py::object& out) {
    Busy busy(this);
    TensorView input = FloatTensor(x, "x", model_->model->metadata().input.channels);
    if (input.height > height_ || input.width > width_) {
      throw py::value_error("x: " + std::to_string(input.height) + "x" +
                            std::to_string(input.width) + " is larger than the session's " +
                            std::to_string(height_) + "x" + std::to_string(width_) +
                            " (make the Session with that size)");
    }
    Result<TensorShape> shape = session_->OutputShape(input.height, input.width);
    ThrowValueIfError(shape.status());
    py::array_t<float> result = OutputArray(out, *shape);
    std::span<float> dst = Floats(result);
    Status finite;
    Status ran;
    {
      py::gil_scoped_release released;
      finite = pipeline::CheckFiniteTensor(input.data(), input.width, input.channels, "x");
      if (finite.ok()) ran = session_->Run(input.data(), input.height, input.width, dst);
    }
    ThrowValueIfError(finite);
    ThrowIfError(ran);
    return result;
  }

  std::string Repr() const {
    return "<sfrt.Session " + model_->path + " at " + std::to_string(height_) + "x" +
           std::to_string(width_) + ", " + IsaName(session_->isa()) + ", " +
           std::to_string(session_->threads()) + " thread(s), " +
           PrecisionSummary(model_->model->metadata()) + ", arena " +
           std::to_string(session_->arena_bytes()) + " bytes>";
  }

  py::tuple size() const { return py::make_tuple(height_, width_); }
  std::string isa() const { return IsaName(session_->isa()); }
  int threads() const { return session_->threads(); }
  std::shared_ptr<PyModel> model() const { return model_; }
  size_t arena_bytes() const { return session_->arena_bytes(); }

 private:
  // One call at a time: a second thread on the same Session gets an error, not a race.
  class Busy {
   public:
    explicit Busy(PySession* s) : s_(s) {
      if (s_->busy_.exchange(true)) {
        throw Error(
            "this Session is running on another thread; give each thread its own "
            "Session (they may share one Model)");
      }
    }
    ~Busy() { s_->busy_.store(false); }
    Busy(const Busy&) = delete;
    Busy& operator=(const Busy&) = delete;

   private:
    PySession* s_;
  };

  // The window builder for this colour order and depth scale (made again when they change).
  pipeline::WindowInput& Window(camera::ColorOrder given, float depth_units) {
    if (!window_ || given_ != given || depth_units_ != depth_units) {
      pipeline::WindowInputOptions options;
      options.height = height_;
      options.width = width_;
      options.allow_aspect_change = allow_aspect_change_;
      options.given = given;
      options.depth_units = depth_units;
      Result<pipeline::WindowInput> w =
          pipeline::WindowInput::Create(model_->model->metadata(), options);
      ThrowValueIfError(w.status());
      window_.emplace(std::move(w).value());
      given_ = given;
      depth_units_ = depth_units;
    }
    return *window_;
  }

  py::array_t<float> RunWindow(const std::array<py::object, 4>& objects,
                               const std::array<std::string, 4>& names, bool rgbd,
                               const std::string& color, float depth_units, const py::object& out) {
    Busy busy(this);
    const InputDesc& desc = model_->model->metadata().input;
    if (desc.is_rgbd() != rgbd || desc.is_tensor()) {
      throw py::value_error(model_->path + " reads " +
                            (desc.is_tensor() ? std::string("a plain tensor: use run_tensor()")
                             : desc.is_rgbd() ? std::string("two RGB-D frames: use run_rgbd()")
                                              : std::string("stereo pairs: use run()")));
    }
    pipeline::WindowInput& window = Window(ParseColor(color), depth_units);
    std::array<py::array, 4> keep;
    std::array<cv::Mat, 4> images;
    for (size_t i = 0; i < 4; ++i) {
      images[i] = rgbd && i % 2 == 1 ? DepthView(objects[i], names[i].c_str(), &keep[i])
                                     : ImageView(objects[i], names[i].c_str(), &keep[i]);
    }
    ThrowValueIfError(window.Check(images, names,
                                   rgbd ? "both frames' colour and depth must "
                                          "have the same size"
                                        : "all four images must have the same "
                                          "size"));
    Result<pipeline::InputSizeChoice> chosen = window.ChooseSize(images[0].rows, images[0].cols);
    ThrowValueIfError(chosen.status());
    if (!chosen->aspect_note.empty()) {
      PyErr_WarnEx(PyExc_UserWarning, chosen->aspect_note.c_str(), 1);
    }
    py::array_t<float> result = OutputArray(out, output_shape_);
    std::span<float> dst = Floats(result);
    input_.resize(window.Floats(height_, width_));
    Status ran;
    {
      py::gil_scoped_release released;
      ran = window.Build(images, height_, width_, input_);
      if (ran.ok()) ran = session_->Run(input_, height_, width_, dst);
    }
    ThrowIfError(ran);
    return result;
  }

  std::shared_ptr<PyModel> model_;
  std::unique_ptr<Session> session_;
  int height_ = 0;
  int width_ = 0;
  bool allow_aspect_change_ = false;
  TensorShape output_shape_;
  std::optional<pipeline::WindowInput> window_;
  camera::ColorOrder given_ = camera::ColorOrder::kBGR;
  float depth_units_ = 0;
  std::vector<float> input_;
  std::atomic<bool> busy_{false};
};

}  // namespace

void BindSession(py::module_& m) {
  py::class_<PySession>(m, "Session", R"doc(
A model planned for one input size: memory, packed weights and kernels are set up here, once;
each run allocates nothing in the library (only the returned array, unless out= is given).

    s = sfrt.Session(m, size=(96, 128), threads=1, isa="auto")
    flow = s.run(left0, right0, left1, right1)        # float32 (H, W, 3)

size:    (H, W) the network runs at; None: the size a trained model records (m.info["input"]
         ["traced_size"]). Images of another size are resized to it as `sfrt infer --size` does.
threads: threads each run uses (the calling one included); 0: one per CPU.
isa:     "auto" (the best this CPU runs) or a name such as "avx2", "avx512", "ref".
allow_aspect_change: take images whose aspect is the inverse of size's (refused otherwise, as a
         likely (W, H) given for (H, W)).

Threads: the GIL is released for the whole of preprocessing and inference, so sessions on
several Python threads run in parallel. Use one Session per thread (a second thread calling a
Session that is running gets sfrt.Error); any number of Sessions may share one Model.
)doc")
      .def(py::init<std::shared_ptr<PyModel>, const py::object&, int, const std::string&, bool>(),
           py::arg("model").none(false), py::arg("size") = py::none(), py::arg("threads") = 1,
           py::arg("isa") = "auto", py::arg("allow_aspect_change") = false)
      .def("run", &PySession::Run, py::arg("left0"), py::arg("right0"), py::arg("left1"),
           py::arg("right1"), py::kw_only(), py::arg("color") = "bgr", py::arg("out") = py::none(),
           R"doc(
Scene flow of one window: the stereo pair at t (left0, right0) and at t+1 (left1, right1).

Images: uint8 arrays (H, W, 3), all of one size (any size: resized to the session's as
`sfrt infer --size` does), in `color` order: "bgr" as OpenCV decodes them (the default), "rgb" as
PIL and imageio do. Arrays whose pixels are packed (C-contiguous, or a crop of one) are read in
place. Returns float32 (h, w, 3): dX, dY, dZ per pixel of left0 in the model's units, exactly what
`sfrt infer` writes for the same images, bit for bit. With out= (float32, C-contiguous, that
shape) the flow is written into it and it is returned.
Raises ValueError for an array of the wrong dtype, shape or size (naming it), sfrt.Error when
the run fails.
)doc")
      .def("run_rgbd", &PySession::RunRgbd, py::arg("color0"), py::arg("depth0"), py::arg("color1"),
           py::arg("depth1"), py::kw_only(), py::arg("depth_units") = 1000.0f,
           py::arg("color") = "bgr", py::arg("out") = py::none(), R"doc(
Scene flow of two RGB-D frames, for models exported with --input-kind rgbd.

color0, color1: uint8 (H, W, 3) in `color` order; depth0, depth1: uint16 (H, W) holding depth *
depth_units (1000: millimetres, most RGB-D cameras; 5000: the TUM benchmark) or float32 (H, W) in
metres; 0, negative or not finite: no depth. Resized to the session's size (depth by the nearest
sample), as `sfrt infer --color0 ... --size` does. Returns float32 (h, w, 3); out= as run().
)doc")
      .def("run_tensor", &PySession::RunTensor, py::arg("x"), py::kw_only(),
           py::arg("out") = py::none(), R"doc(
Runs the network on its input tensor as given, as `sfrt infer --input-npy` does.

x: float32 (H, W, C) or (1, H, W, C), C the model's input channels, already in its channel
order and normalised; H and W at most the session's size. Non-finite values are refused
(ValueError naming the element). Returns float32 (h, w, 3); out= as run().
)doc")
      .def_property_readonly("size", &PySession::size, "(H, W) the session runs at.")
      .def_property_readonly("isa", &PySession::isa, "The instruction set its kernels use.")
      .def_property_readonly("threads", &PySession::threads, "Threads each run uses.")
      .def_property_readonly("model", &PySession::model, "The Model it runs (kept alive).")
      .def_property_readonly("arena_bytes", &PySession::arena_bytes,
                             "Bytes of activation memory planned at creation.")
      .def("__repr__", &PySession::Repr);
}

}  // namespace sfrt::python
