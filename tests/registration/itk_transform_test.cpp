// ITK reads our .tfm back (the independent reader: ITK 5's own transform IO), and maps image
// points to the same robot points as the registration.
#include <gtest/gtest.h>

#include <itkAffineTransform.h>
#include <itkTransformFileReader.h>
#include <itkTxtTransformIOFactory.h>

#include <Eigen/Geometry>

#include "ignav/registration/slicer_export.hpp"

namespace ignav::registration {
namespace {

TEST(ItkTransformFile, ItkReadsTheSameImageToRobotMap) {
  const std::vector<Eigen::Vector3d> image{{-12, -6, -18}, {14, -4, 6}, {2, 16, 20}, {5, 5, 5}};
  const Eigen::Matrix3d rotation =
      Eigen::AngleAxisd(0.9, Eigen::Vector3d(0.3, -1, 0.5).normalized()).toRotationMatrix();
  std::vector<Eigen::Vector3d> robot;
  for (const auto& p : image)
    robot.push_back(1.02 * rotation * p + Eigen::Vector3d(3, -140, 7));
  auto reg = registerPoints(image, robot, TransformKind::kSimilarity, RegistrationLimits{});
  ASSERT_TRUE(reg.ok()) << reg.error().message;
  const std::string path = ::testing::TempDir() + "/ignav_image_to_robot.tfm";
  ASSERT_TRUE(writeItkTransform(*reg, path).ok());

  // Registered explicitly rather than through ITK's generated factory-registration header.
  itk::TxtTransformIOFactory::RegisterOneFactory();
  using Reader = itk::TransformFileReaderTemplate<double>;
  auto reader = Reader::New();
  reader->SetFileName(path);
  ASSERT_NO_THROW(reader->Update());
  ASSERT_EQ(reader->GetTransformList()->size(), 1u);
  using Affine = itk::AffineTransform<double, 3>;
  auto* affine = dynamic_cast<Affine*>(reader->GetTransformList()->front().GetPointer());
  ASSERT_NE(affine, nullptr) << reader->GetTransformList()->front()->GetNameOfClass();
  for (const Eigen::Vector3d& p :
       {image[0], image[3], Eigen::Vector3d(40, -60, 100), Eigen::Vector3d(0, 0, 0)}) {
    Affine::InputPointType in;
    for (unsigned a = 0; a < 3; ++a)
      in[a] = p[a];
    const auto out = affine->TransformPoint(in);
    const Eigen::Vector3d expected = reg->toRobot(p);
    for (unsigned a = 0; a < 3; ++a)
      EXPECT_NEAR(out[a], expected[a], 1e-9);
  }
}

// A rotation about one axis has exact zeros that arithmetic may make negative (-R^T t, R^T of a
// -0 term): the file says 0, as any tool would write it.
TEST(ItkTransformFile, ExactZerosAreWrittenWithoutASign) {
  Registration reg;
  reg.kind = TransformKind::kRigid;
  reg.rotation = Eigen::AngleAxisd(0.35, Eigen::Vector3d::UnitY()).toRotationMatrix();
  reg.rotation(1, 0) = -0.0;
  reg.rotation(0, 1) = -0.0;
  reg.translation_mm = Eigen::Vector3d(8.5, -0.0, -161.0);
  const std::string text = itkTransformText(reg);
  EXPECT_EQ(text.find("-0 "), std::string::npos) << text;
  EXPECT_EQ(text.find(" -0\n"), std::string::npos) << text;
}

}  // namespace
}  // namespace ignav::registration
