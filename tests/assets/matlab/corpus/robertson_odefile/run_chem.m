k1 = 0.04; k2 = 3e7; k3 = 1e4;
[t,y] = ode15s('chem',[],[],[],k1,k2,k3);
semilogx(t,y(:,2)*1e4)
