// vtk.js modules the package ships without a declaration: only what the 3D view calls.
declare module "@kitware/vtk.js/Filters/Core/PolyDataNormals" {
  import type { vtkAlgorithm, vtkObject } from "@kitware/vtk.js/interfaces";
  import type vtkPolyData from "@kitware/vtk.js/Common/DataModel/PolyData";
  interface vtkPolyDataNormals extends vtkObject, vtkAlgorithm {
    setInputData(data: vtkPolyData): void;
    update(): void;
    getOutputData(): vtkPolyData;
  }
  const vtkPolyDataNormals: { newInstance(initial?: object): vtkPolyDataNormals };
  export default vtkPolyDataNormals;
}
