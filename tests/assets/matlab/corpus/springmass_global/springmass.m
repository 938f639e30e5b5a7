function dz = springmass(t,z)
%SPRINGMASS a forced mass-spring-damper; parameters are globals
global mass kstiff cdamp zeta famp fomega;

force = famp*cos(fomega*t);

dz(1,1) = z(2);
dz(2,1) = (-kstiff*z(1)-cdamp*z(2))/mass + force/mass;

end
