# radioactive decay chain A -> B -> C, written for Octave
1;
function dy = chain(t, y)
  ka = 0.5;  # 1/h
  kb = 0.2;  # 1/h
  dy = [-ka*y(1); ka*y(1) - kb*y(2); kb*y(2)];
endfunction

opts = odeset("RelTol", 1e-6, "AbsTol", 1e-9);
[t, y] = ode45(@chain, [0 24], [1 0 0], opts);
printf("final: %g %g %g\n", y(end, :));
