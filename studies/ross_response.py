"""Reference numbers of tests/test_response.py::test_unbalance_response_matches_ross_without_shear: ROSS 2.3.0's
unbalance response of the critical_speed rotor (Rayleigh beam: shear off). Run with ROSS's own interpreter:
/work/rossvenv/bin/python studies/ross_response.py (prints one JSON line: the disk's complex response)."""
import numpy as np, ross as rs, json
steel = rs.Material(name="steel_cs", rho=7850.0, E=2.1e11, G_s=2.1e11/2/1.3)
sh = [rs.ShaftElement(L=0.05, idl=0.0, odl=0.04, material=steel, shear_effects=False, rotary_inertia=True, gyroscopic=True) for _ in range(20)]
disk = rs.DiskElement(n=10, m=20.0, Id=0.13, Ip=0.25)
b0 = rs.BearingElement(n=0, kxx=5e5, kyy=2e6, cxx=2000.0, cyy=2000.0)
b1 = rs.BearingElement(n=20, kxx=5e5, kyy=2e6, cxx=2000.0, cyy=2000.0)
rotor = rs.Rotor(sh, [disk], [b0, b1])
f = np.array([15.0, 24.0, 26.0, 31.0, 40.0])
r = rotor.run_unbalance_response(node=10, unbalance_magnitude=5e-4, unbalance_phase=0.0, frequency=2*np.pi*f)
Z = r.forced_resp
n = rotor.number_dof
print(json.dumps({"f": f.tolist(), "x_re": Z[n*10].real.tolist(), "x_im": Z[n*10].imag.tolist(), "y_re": Z[n*10+1].real.tolist(), "y_im": Z[n*10+1].imag.tolist(), "ndof_node": n}))
